"""What a conformance check says (:class:`CheckResult`: PASS, FAIL, SKIP or NOTE, with what to
fix) and the report ``beacon-sim check`` prints of them (:func:`print_report`)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class CheckResult:
    """One check: its name, whether it passed, what was seen, and what to fix."""

    name: str
    passed: bool
    message: str = ""
    advice: str = ""
    #: False: nothing to judge it on (the filter never got that far): printed "SKIP", not
    #: "PASS", and not counted as passed.
    judged: bool = True
    #: Not a check at all (the cost, where the output went): printed "NOTE", not counted.
    note: bool = False

    @property
    def mark(self) -> str:
        """How the report marks it: PASS, FAIL, SKIP (not judged) or NOTE (not a check)."""
        if self.note:
            return "NOTE"
        if not self.passed:
            return "FAIL"
        return "PASS" if self.judged else "SKIP"


def verdict(name: str, passed: object, message: str = "", advice: str = "", *,
            note: bool = False) -> CheckResult:
    """A CheckResult whose advice is kept only when the check failed; a passing one whose
    message says "not judged" was not judged (SKIP); ``note``: not a check (NOTE)."""
    judged = not (passed and message.startswith("not judged"))
    return CheckResult(name, bool(passed), message, "" if passed else advice, judged, note)


#: What a check that had nothing to judge says when no step of any run returned.


NO_STEP = "not judged: no step returned an estimate (see runs)"


def print_report(spec: str, results: list[CheckResult]) -> None:
    """One line per check, then what to fix for each failure."""
    print(f"conformance of {spec}:")
    width = max((len(r.name) for r in results), default=0)
    for r in results:
        print(f"  {r.mark}  {r.name:<{width}}  {r.message}")
    failed = [r for r in results if not r.passed]
    if failed:
        print("what to fix:")
        for r in failed:
            print(f"  - {r.name}: {r.advice}")
    checks = [r for r in results if not r.note]
    skipped = sum(1 for r in checks if r.mark == "SKIP")
    passed = sum(1 for r in checks if r.mark == "PASS")
    print(f"{passed} of {len(checks)} checks passed"
          + (f"; {skipped} not judged (the filter never got that far)" if skipped else ""))


__all__ = ["NO_STEP", "CheckResult", "print_report", "verdict"]
