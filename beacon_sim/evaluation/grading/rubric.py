"""A course's rubric (``[[rubric]]`` in a grade config): points per test, scored from a
student's runs, the form course autograders for localization labs use (docs/grading.md, "A
grade a course platform takes"):

``builds``       builds tracking within ``within_s`` [s]: the position error falls to
                 ``error_m`` [m] or less by then; points x the share of runs that did.
``keeps``        keeps tracking: the share of ticks (from ``after_s`` [s] on) with the position
                 error at most ``error_m``; full points at ``share`` or more, in proportion
                 below.
``accuracy``     accuracy against the bound: full points at RMSE/PCRB ``max_ratio`` or less,
                 none at ``zero_ratio`` (default twice ``max_ratio``) or more, linear between.
``consistency``  full points when the row's consistency word is "consistent", none otherwise.

A student whose filter failed in any run, or whose result is suspicious (kept out of the
ranking), gets no points on any test, with the reason. Every test says what was measured.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

#: The rubric's test kinds.
KINDS = ("builds", "keeps", "accuracy", "consistency")
#: Gradescope's visibility settings (its documented values).
VISIBILITIES = ("visible", "hidden", "after_due_date", "after_published")
#: Each kind's keys beside ``test``, ``name``, ``points`` and ``visibility``, and defaults.
KIND_KEYS: dict[str, dict[str, float | None]] = {
    "builds": {"within_s": None, "error_m": 0.5},
    "keeps": {"error_m": 0.5, "share": 0.9, "after_s": 0.0},
    "accuracy": {"max_ratio": 1.5, "zero_ratio": None},
    "consistency": {},
}


class RubricError(ValueError):
    """A bad ``[[rubric]]`` entry (one line naming the file, the entry and the key)."""


@dataclass(frozen=True)
class RubricItem:
    """One test of the rubric: its kind (:data:`KINDS`), its name as the platform shows it,
    its points, its visibility, and its kind's settings (``within_s``, ``error_m``,
    ``share``, ``after_s``, ``max_ratio``, ``zero_ratio``; None where the kind has none)."""

    test: str
    name: str
    points: float
    visibility: str = "visible"
    within_s: float | None = None
    error_m: float | None = None
    share: float | None = None
    after_s: float | None = None
    max_ratio: float | None = None
    zero_ratio: float | None = None


def _default_name(kind: str, s: dict[str, Any]) -> str:
    if kind == "builds":
        return f"builds tracking within {s['within_s']:g} s (error {s['error_m']:g} m or less)"
    if kind == "keeps":
        return (f"keeps tracking (share of time within {s['error_m']:g} m, full marks at "
                f"{s['share']:.0%})")
    if kind == "accuracy":
        return f"accuracy against the bound (RMSE/PCRB {s['max_ratio']:g} or less)"
    return "consistency (ANEES in its band)"


def parse_rubric(path: str | Path, value: object,
                 error: type[Exception] = RubricError) -> tuple[RubricItem, ...]:
    """``[[rubric]]`` of a config file as :class:`RubricItem` s; a bad entry raises
    ``error`` with one line (file, ``rubric[i].key``, what was expected)."""
    if not isinstance(value, list) or not 1 <= len(value) <= 100 \
            or not all(isinstance(v, dict) for v in value):
        raise error(f"{path}: rubric: expected 1 to 100 [[rubric]] tables")
    out = []
    for i, entry in enumerate(value):
        where = f"{path}: rubric[{i}]"
        kind = entry.get("test")
        if kind not in KINDS:
            raise error(f"{where}.test = {kind!r}: expected one of {', '.join(KINDS)}")
        allowed = {"test", "name", "points", "visibility", *KIND_KEYS[kind]}
        unknown = sorted(set(entry) - allowed)
        if unknown:
            raise error(f"{where}: unknown key(s) {', '.join(unknown)} for test {kind!r}; "
                        f"known: {', '.join(sorted(allowed))}")
        settings: dict[str, Any] = {}
        for key, default in KIND_KEYS[kind].items():
            v = entry.get(key, default)
            if v is None and key == "within_s":
                raise error(f"{where}.within_s: missing; expected the seconds a filter has to find "
                            "the robot")
            if v is None:
                settings[key] = None
                continue
            positive = key in ("error_m", "max_ratio", "zero_ratio", "share")
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) or v < 0 \
                    or (key == "share" and v > 1) or (positive and v <= 0):
                raise error(f"{where}.{key} = {v!r}: expected a "
                            + ("share in (0, 1]" if key == "share" else "positive number"))
            settings[key] = float(v)
        if kind == "accuracy" and settings["zero_ratio"] is None:
            settings["zero_ratio"] = 2.0 * settings["max_ratio"]
        if kind == "accuracy" and settings["zero_ratio"] <= settings["max_ratio"]:
            raise error(f"{where}.zero_ratio = {settings['zero_ratio']!r}: expected more than max_ratio")
        points = entry.get("points", 1.0)
        if isinstance(points, bool) or not isinstance(points, int | float) or not (0 < points <= 1e6):
            raise error(f"{where}.points = {points!r}: expected a number in (0, 1e6]")
        vis = entry.get("visibility", "visible")
        if vis not in VISIBILITIES:
            raise error(f"{where}.visibility = {vis!r}: expected one of {', '.join(VISIBILITIES)}")
        name = entry.get("name", _default_name(kind, settings))
        if not isinstance(name, str) or not name.strip() or len(name) > 200:
            raise error(f"{where}.name = {name!r}: expected a text of 1 to 200 characters")
        out.append(RubricItem(kind, name, float(points), str(vis), **settings))
    return tuple(out)


def tracking_figures(err: np.ndarray, dt: float, item: RubricItem) -> dict[str, Any]:
    """One run's tracking figures for ``item`` from its pose errors ``err`` (T, 3) [m, m,
    rad] (NaN after a failure: not within): ``built_s``, the end of the first tick whose
    position error is within ``error_m`` (None: never), and ``share``, the share of the ticks
    from ``after_s`` on that are within it."""
    perr = np.hypot(err[:, 0], err[:, 1])
    within = np.isfinite(perr) & (perr <= float(item.error_m or 0.0))
    hit = np.flatnonzero(within)
    built = float((hit[0] + 1) * dt) if hit.size else None
    start = min(len(perr), math.floor((item.after_s or 0.0) / dt + 1e-9))
    share = float(within[start:].mean()) if len(perr) > start else 0.0
    return {"built_s": built, "share": share}


def score_row(row: dict[str, Any], rubric: Sequence[RubricItem],
              tracks: dict[int, list[dict[str, Any]]]) -> list[dict[str, Any]]:
    """The rubric's tests for one student's row: ``name``, ``score``, ``max_score``,
    ``output`` (what was measured, or why no points), ``visibility``. ``tracks``: per rubric
    index of a tracking test, each single-robot run's :func:`tracking_figures`."""
    out = []
    held = None
    if row["failed_runs"]:
        first = row["failures"][0] if row["failures"] else {"reason": "failed"}
        held = (f"no points: the filter failed in {row['failed_runs']} of {row['runs']} runs "
                f"({first['reason']})")
    elif row.get("suspicious"):
        held = f"no points until reviewed: suspicious, {row['suspicious']}"
    for i, item in enumerate(rubric):
        score, text = 0.0, held
        if held is None:
            score, text = _score_item(row, item, tracks.get(i, []))
        out.append({"name": item.name, "score": round(float(score), 6), "max_score": item.points,
                    "output": text, "visibility": item.visibility})
    return out


def _score_item(row: dict[str, Any], item: RubricItem, runs: list[dict[str, Any]]) -> tuple[float, str]:
    """One test's points and what was measured."""
    if item.test in ("builds", "keeps") and not runs:
        return 0.0, "no points: no single-robot run to measure tracking on"
    if item.test == "builds":
        ok = [r["built_s"] is not None and r["built_s"] <= float(item.within_s or 0.0) + 1e-9 for r in runs]
        times = ", ".join("never" if r["built_s"] is None else f"{r['built_s']:.2f} s" for r in runs)
        return (item.points * sum(ok) / len(ok),
                f"{sum(ok)} of {len(ok)} runs within {item.error_m:g} m by {item.within_s:g} s "
                f"(first within: {times})")
    if item.test == "keeps":
        share = float(np.mean([r["share"] for r in runs]))
        need = float(item.share or 1.0)
        return (item.points * min(1.0, share / need),
                f"{share:.1%} of the time within {item.error_m:g} m from {item.after_s:g} s on "
                f"(mean over {len(runs)} runs; full marks at {need:.0%})")
    if item.test == "accuracy":
        ratio = row.get("rmse_over_pcrb")
        if ratio is None or not math.isfinite(ratio):
            return 0.0, "no points: no bound to compare with (RMSE/PCRB not defined here)"
        lo, hi = float(item.max_ratio or 1.0), float(item.zero_ratio or 2.0)
        frac = 1.0 if ratio <= lo else 0.0 if ratio >= hi else (hi - ratio) / (hi - lo)
        return item.points * frac, (f"RMSE/PCRB {ratio:.2f} (position RMSE {row['pos_rmse_m']:.4f} m); "
                                    f"full marks at {lo:g} or less, none at {hi:g}")
    word = str(row.get("anees_verdict"))
    anees = row.get("anees")
    shown = "-" if anees is None else f"{anees:,.2f}"
    return (item.points if word == "consistent" else 0.0), f"ANEES {shown}: {word}"


def total(tests: list[dict[str, Any]]) -> float:
    """The rubric score: the sum of the tests' scores (rounded as each is)."""
    return round(sum(t["score"] for t in tests), 6)
