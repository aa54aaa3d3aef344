"""The filters of a replay: which recorded filters are run from a file (built-ins and installed
entry points only, never imported code), their recorded settings, and their estimates checked
tick by tick against the recording's (``FilterVerifier``); ``ReplayMismatch`` when they differ."""

from __future__ import annotations

from collections.abc import Sequence
from types import SimpleNamespace
from typing import Any

import numpy as np

from beacon_sim.hosting.loading import filter_names, split_label
from beacon_sim.hosting.team_specs import MEMBER_PREFIX, team_filter_name
from beacon_sim.io.recording import (
    EstimateDigests,
    Recording,
    RecordingError,
    effective_params,
    recorded_tracks,
)
from beacon_sim.runs.replay_maths import (
    TOLERANCE_TEXT,
    Difference,
    Maths,
    estimate_difference,
)


class ReplayMismatch(RecordingError):
    """The replayed truth, readings, filter settings or estimates differ from the recorded
    ones (the message names the field)."""


def _first_difference(recorded: Any, replayed: Any, where: str) -> str:
    """``where.KEY`` of the first parameter that differs, with both values."""
    if isinstance(recorded, dict) and isinstance(replayed, dict):
        for k in sorted(set(recorded) | set(replayed)):
            if recorded.get(k, "(absent)") != replayed.get(k, "(absent)"):
                return _first_difference(recorded.get(k, "(absent)"), replayed.get(k, "(absent)"),
                                         f"{where}.{k}")
    rec, rep = repr(recorded), repr(replayed)
    return f"{where} recorded as {rec[:40]}, but {rep[:40]} now"


class FilterVerifier:
    """What a replay checks about the filters (version 3 files): the filters line's
    effective parameters against the filters the replay built (so an edited header
    ``filters`` list or ``params``, or an edited ``[filters.NAME]`` in the stored scenario,
    is named), then each filter's estimate digests at every estimates line and at the end.

    The digests match bit for bit only on the maths the file was made with (``maths``,
    :class:`~beacon_sim.runs.replay_maths.Maths`). On other maths (version 4 files) a
    filter whose digest differs is compared by its stored estimate values, within the
    tolerance (``differences``: the largest difference of each); beyond it, or on a file
    that does not say which maths made it (version 3), it is listed as not verified rather
    than called an edit. Stored values must equal the replay's bit for bit wherever the
    digests match (an edited value is named).

    Compared only when the replay runs the recorded filters with the recorded parameters
    (``compare``); a filter the replay skipped (named by file) or that was switched off or
    reloaded live is listed in :meth:`coverage` instead. ``runner``: the replay's filters
    (a TeamRunner, or anything :func:`~beacon_sim.io.recording.recorded_tracks` reads),
    seen as the recording stores them."""

    def __init__(self, recording: Recording, runner: Any, compare: bool, skipped: list[str]):
        self.recording = recording
        self.runner = runner
        self.compare = compare and recording.parts.settings is not None
        self.skipped = list(skipped)
        self.digests = EstimateDigests()
        self.unchecked: dict[str, str] = {}  # name -> why its estimates were not compared
        self.compared_lines = 0
        self.maths = Maths.of(recording.header)
        self.differences: dict[str, Difference] = {}  # other maths: largest, within tolerance

    @property
    def tracks(self) -> dict[str, Any]:
        """The replay's tracks by filter name, as the recording stores them (now: a filter
        reloaded in the window has a new track)."""
        return {} if self.runner is None else recorded_tracks(self.runner)

    def check_settings(self) -> str | None:
        """Why the built filters are not the recorded ones (naming the field), or None."""
        if not self.compare:
            return None
        settings = self.recording.parts.settings or {}
        line = self.recording.parts.settings_line
        tracks = self.tracks
        names = set(tracks)
        recorded = set(settings) - set(self.skipped)
        if names != recorded:
            extra = sorted(names - recorded) or sorted(recorded - names)
            return (f"the header's filters list differs from the filters line (line {line}: "
                    f"filter {extra[0]!r} is in one of them only)")
        for name in sorted(names):
            track = tracks[name]
            if "failed" in settings[name]:  # (e.g. over the window's time limit to build)
                self.unchecked[name] = f"not built live ({str(settings[name]['failed'])[:80]})"
                continue
            replayed = effective_params(track.filter) if track.filter is not None else None
            rec = settings[name].get("params")
            if rec != replayed and track.filter is not None:
                replayed = without_added_defaults(rec, replayed, default_params(track.filter))
            if rec != replayed:
                return (f"the filter settings (line {line}) differ from the header's params and "
                        f"the stored scenario: {_first_difference(rec, replayed, name)}")
        return None

    def fold(self, tick: int) -> None:
        """The tick's estimates into the digests (once per tick, after the filters were fed)."""
        self.digests.update(tick, self.tracks)

    def compare_line(self, tick: int, line: dict[str, Any] | None) -> str | None:
        """Why the digests differ from an estimates line's (or the end line's) of ``tick``
        (naming the filter), or None."""
        if line is None or not self.compare:
            return None
        tracks = self.tracks
        notes = line.get("notes", {})
        values = line.get("values", {})
        recorded = line.get("digests", line.get("estimates", {}))
        for name, digest in sorted(recorded.items()):
            if name in self.skipped:
                continue
            if name not in tracks:
                return f"filter {name!r} of the estimates line is not among the recorded filters"
            if digest is None or name in self.unchecked:
                self.unchecked.setdefault(name, notes.get(name, "not compared"))
                continue
            mine = self.digests.values(name, tick)
            if digest == self.digests.digest(name):
                if values.get(name) is not None and not _same_bits(values[name], mine):
                    return f"the estimate values of filter {name} (tick {tick})"
                continue
            if name in notes or tracks[name].failed:
                self.unchecked[name] = notes.get(name) or f"switched off in this replay: " \
                                                          f"{tracks[name].failed}"
                continue
            if self.maths.known and self.maths.same:
                return f"the estimates of filter {name} (their digest after tick {tick})"
            self._other_maths(name, tick, values.get(name), mine)
        self.compared_lines += 1
        return None

    def _other_maths(self, name: str, tick: int, recorded: Sequence[float] | None,
                     replayed: Sequence[float] | None) -> None:
        """A filter whose digest differs on other maths (or maths the file does not name):
        within the tolerance, its largest difference is kept; else it is not verified."""
        if not self.maths.known:
            self.unchecked[name] = ("its estimates differ from the recorded ones: not verified "
                                    "(the file does not say which maths made it)")
            return
        if recorded is None or replayed is None:
            self.unchecked[name] = (f"not verified (different maths): no estimate values "
                                    f"to compare at tick {tick}")
            return
        diff = estimate_difference(recorded, replayed)
        if diff.within:
            self.differences[name] = diff.worst(self.differences.get(name, Difference()))
            return
        self.unchecked[name] = (f"not verified (different maths): its estimates differ from "
                                f"the recorded ones by {diff.text()} at tick {tick}, beyond "
                                f"the tolerance")

    def coverage(self) -> tuple[list[str], str, str]:
        """What the check covered beyond truth and readings: (each thing it could not
        verify, with why; what it did verify, in words; on other maths, how the estimates
        compared). An empty list: everything was compared bit for bit."""
        gaps, checked = self._gaps()
        return gaps, checked, self.maths_note()

    def maths_note(self) -> str:
        """"" on the maths the file was made with (or a file that does not say); else that
        the maths differ, and how the estimates compared."""
        m = self.maths
        if not m.known or m.same:
            return ""
        if not self.compare or not self.compared_lines:
            return f"; {m.differs_text()}"  # (what was verified: the status before it)
        note = f"; {m.differs_text()}: inputs verified bit for bit"
        exact = sorted(set(self.tracks) - set(self.skipped) - set(self.unchecked)
                       - set(self.differences))
        which = "the other estimates" if self.unchecked else "estimates"
        if not self.differences:
            return note + (f", {which} still bit for bit" if exact else "")
        worst = Difference()
        for d in self.differences.values():
            worst = worst.worst(d)
        return (note + f", {which} within the tolerance ({TOLERANCE_TEXT}; largest difference "
                f"{worst.text()})")

    def _gaps(self) -> tuple[list[str], str]:
        gaps, checked = self._filter_gaps()
        rec = self.recording
        if rec.parts.map_unverified and rec.parts.signature != "signed and verified":
            gaps.insert(0, rec.parts.map_unverified)
        return gaps, checked

    def _filter_gaps(self) -> tuple[list[str], str]:
        rec = self.recording
        if not rec.filters and not self.tracks:  # no filter ran: nothing of theirs to check
            return ([] if rec.version > 1 else ["the readings (a version 1 file does not record them)"],
                    "truth and readings" if rec.version > 1 else "the truth")
        if rec.version == 1:
            return ["the readings and filter settings (a version 1 file records neither)"], "the truth"
        if rec.version == 2:
            return (["the filter settings and estimates (a version 2 file records neither)"],
                    "truth and readings")
        if rec.parts.settings is None:
            return ["the filter settings and estimates (not recorded)"], "truth and readings"
        if not self.compare:
            return (["the estimates (other filters or parameters than the recorded ones)"],
                    "truth and readings")
        if not self.compared_lines and rec.parts.estimates == {} and not (rec.end or {}).get("estimates"):
            return ["the estimates (none recorded)"], "truth, readings and filter settings"
        out = [f"{n} (not run: named by a file or module)" for n in self.skipped]
        out += [f"{n}: {why}" for n, why in sorted(self.unchecked.items())]
        return out, "truth, readings, filter settings and the other estimates"


def _same_bits(recorded: Sequence[float], replayed: Sequence[float] | None) -> bool:
    """Whether stored estimate values are the replay's bit for bit."""
    if replayed is None or len(recorded) != len(replayed):
        return False
    return np.asarray(recorded, dtype="<f8").tobytes() == np.asarray(replayed, dtype="<f8").tobytes()


def default_params(flt: Any) -> dict[str, Any] | None:
    """A built filter's class defaults in the shape :func:`effective_params` gives its
    parameters (an ``independent:F``'s copies' under ``members``), as JSON values."""
    defaults = getattr(type(flt), "defaults", None)
    out: dict[str, Any] = dict(defaults) if isinstance(defaults, dict) else {}
    members = getattr(flt, "filters", None)
    if isinstance(members, list) and members:
        out["members"] = [default_params(m) for m in members]
    return effective_params(SimpleNamespace(params=out)) if out else None


def without_added_defaults(recorded: Any, replayed: Any, defaults: Any) -> Any:
    """``replayed`` without the parameters ``recorded`` lacks and that are at their class
    default: parameters a newer beacon-sim added to a filter (such as ``association``),
    which a file written before cannot hold. Any other difference stays, and the estimate
    digests still check that the filter gave the recorded estimates bit for bit."""
    if isinstance(recorded, dict) and isinstance(replayed, dict) and isinstance(defaults, dict):
        out = {}
        for k, v in replayed.items():
            if k not in recorded and k in defaults and v == defaults[k]:
                continue
            out[k] = without_added_defaults(recorded.get(k), v, defaults.get(k))
        return out
    if isinstance(recorded, list) and isinstance(replayed, list) and isinstance(defaults, list) \
            and len(recorded) == len(replayed) == len(defaults):
        return [without_added_defaults(r, p, d) for r, p, d in zip(recorded, replayed, defaults, strict=True)]
    return replayed


def settings_error(recording: Recording, why: str) -> ReplayMismatch:
    """The error of a replay whose filters are not the recorded ones (``why`` names the field)."""
    return ReplayMismatch(f"{recording.path}:{recording.parts.settings_line}: {why}: was it edited?")


def settings_compared(recording: Recording, specs: list[str],
                      recorded_specs: list[str], used: dict[str, dict[str, Any]]) -> bool:
    """Whether a replay runs exactly the recorded filters with the recorded parameters
    (``used``: the parameters it builds them with), so that their settings and estimates
    can be compared with the file's."""
    clean = {k: v for k, v in used.items() if v}
    return list(specs) == list(recorded_specs) \
        and clean == {k: v for k, v in recording.params.items() if v}


def is_builtin_spec(spec: str) -> bool:
    """A filter spec a recording may run: a built-in filter or team filter by name, an
    installed entry point, or ``independent:F`` with F one of those (each optionally
    labelled). Anything naming a module or a file (``alice.py:MyEkf``, ``pkg.mod:Class``,
    ``independent:alice.py:MyEkf``) is not: a recording never makes beacon-sim import code."""
    _, body = split_label(spec)
    if body.startswith(MEMBER_PREFIX):
        body = body[len(MEMBER_PREFIX):]
    return bool(body) and ":" not in body and "/" not in body and "\\" not in body \
        and not body.endswith(".py")


def recorded_filter_specs(recording: Recording, requested: list[str] | None) -> tuple[list[str], list[str]]:
    """(filters to run, recorded filters skipped): ``requested`` when given (even empty);
    otherwise the recorded built-in ones (named by module or file path: skipped)."""
    if requested is not None:
        return list(requested), []
    return ([s for s in recording.filters if is_builtin_spec(s)],
            [s for s in recording.filters if not is_builtin_spec(s)])


def recorded_names(recording: Recording, specs: list[str]) -> list[str]:
    """The names a run of ``recording``'s robots gives filter specs (a single robot's as
    ``run`` names them, a team's as a team run does)."""
    return [team_filter_name(s) for s in specs] if recording.is_team else filter_names(specs)


def recorded_params(recording: Recording,
                    params: dict[str, dict[str, Any]] | None) -> dict[str, dict[str, Any]]:
    """The recorded filter parameters with ``params`` (from ``--set``) on top."""
    merged = recording.params
    for name, p in (params or {}).items():
        merged.setdefault(name, {}).update(p)
    return merged


def skipped_note(spec: str) -> str:
    """The line telling the user a recorded filter was not run, and how to run it."""
    return (f"note: recorded filter {spec} not run (a recording never makes beacon-sim import "
            f"code); pass --filter {spec} to run it")


def replay_verifier(recording: Recording, runner: Any, specs: list[str],
                    used: dict[str, dict[str, Any]]) -> FilterVerifier:
    """The filter settings and estimates check of a replay running ``specs`` with the
    parameters ``used`` (compared only when they are the recorded ones)."""
    recorded, skipped = recorded_filter_specs(recording, None)
    return FilterVerifier(recording, runner, settings_compared(recording, specs, recorded, used),
                          recorded_names(recording, skipped) if skipped else [])


__all__ = ["FilterVerifier", "ReplayMismatch", "default_params", "is_builtin_spec",
           "recorded_filter_specs", "recorded_names", "recorded_params", "replay_verifier",
           "settings_compared", "settings_error", "skipped_note", "without_added_defaults"]
