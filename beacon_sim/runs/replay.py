"""Replaying a recording bit for bit, with the recorded filters or any others, over any
number of robots (a single robot's file is a team of one).

The one home of "how a recording is replayed": :func:`replay_recording` re-simulates a
file headless and checks its checksums; :class:`ReplaySession` is the same, one tick at a
time, for the window. The file format is beacon_sim/io/recording.py (and docs/replay.md).

Each tick goes as it went live: the recorded user commands (a kidnap of the robot it names,
a reset of the filters), then every robot steps, the recorded driven robot on its recorded
command (or, on a team's file where its own driver chose it live, that driver again, so the
driver's state follows), the others on their drivers; then the filters are fed
(:class:`~beacon_sim.hosting.team_runner.TeamRunner`: each single-robot filter on each
robot, each team filter once). A recording never makes beacon-sim import code: only
built-in filters and installed entry points are run from a file
(:func:`is_builtin_spec`).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence, Set
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

from beacon_sim.core.team import TeamSimulation, TeamStep
from beacon_sim.core.types import Control
from beacon_sim.hosting.loading import filter_names, split_label
from beacon_sim.hosting.runner import HEADLESS_STEP_LIMIT_S
from beacon_sim.hosting.team_runner import TeamRunner
from beacon_sim.hosting.team_specs import MEMBER_PREFIX, team_filter_name
from beacon_sim.io.recording import (
    EstimateDigests,
    Recording,
    RecordingError,
    TickRecord,
    effective_params,
    recorded_tracks,
    recording_key,
)
from beacon_sim.runs.headless import RunResult
from beacon_sim.runs.live import Session
from beacon_sim.runs.recorder import TeamReadingsHash
from beacon_sim.runs.replay_maths import (
    TOLERANCE_TEXT,
    Difference,
    Maths,
    estimate_difference,
    old_maths_text,
)
from beacon_sim.runs.user_commands import apply_to_run


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


def with_signature(status: str, recording: Recording) -> str:
    """The status with what the signature proved ("signed and verified" in place of
    "verified" when the HMAC matched; "not signed" when a key was given). A signature that
    does not match raises ReplayMismatch (after the replay's own checks, which name a field)."""
    if recording.parts.signature_error:
        raise ReplayMismatch(recording.parts.signature_error)
    sig = recording.parts.signature
    if sig == "signed and verified" and status.startswith("verified"):
        return "signed and " + status
    if sig == "not signed":
        return status + ("; not signed" if recording_key() is not None else "")
    return f"{status}; {sig}"


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


class ReplayedTruth:
    """The checksums of a replayed run as its recording holds them: a single robot's file,
    its robot's ``Simulation`` checksums and pose; a team's, the team's
    (``TeamSimulation.truth_checksum``, :class:`~beacon_sim.runs.recorder.TeamReadingsHash`,
    every robot's pose)."""

    def __init__(self, recording: Recording, sim: TeamSimulation):
        self.recording = recording
        self.sim = sim
        self.team = recording.is_team
        self._readings = TeamReadingsHash()

    def observe(self, step: TeamStep) -> None:
        """A tick just run (a team's readings go into their checksum)."""
        if self.team:
            self._readings.update(step)

    @property
    def truth(self) -> str:
        return self.sim.truth_checksum if self.team else self.sim.sims[0].truth_checksum

    @property
    def readings(self) -> str:
        return self._readings.checksum if self.team else self.sim.sims[0].readings_checksum

    def poses_match(self, line: dict[str, Any]) -> bool:
        """Whether a checkpoint or end line's true pose(s) are the simulation's now."""
        if self.team:
            return line.get("poses") == self.sim.poses.tolist()
        return line.get("pose") == [float(v) for v in self.sim.sims[0].pose]

    def state_differs(self, line: dict[str, Any]) -> bool:
        """Whether a checkpoint or end line differs from the replay now (truth, readings,
        poses)."""
        return (line["checksum"] != self.truth
                or line.get("readings_checksum", self.readings) != self.readings
                or not self.poses_match(line))

    def tick_mismatch(self, rec: TickRecord) -> str | None:
        """What the tick's recorded checksums disagree with after the tick ran, or None."""
        return checksums_mismatch(rec, self.truth, self.readings)


def checksums_mismatch(rec: TickRecord, truth: str, readings: str) -> str | None:
    """What a tick's recorded checksums disagree with (the replay's ``truth`` and
    ``readings`` checksums after the tick), or None."""
    if rec.short_checksum is not None and truth[:8] != rec.short_checksum:
        return "its truth checksum"
    if rec.readings_checksum is not None and readings[:8] != rec.readings_checksum:
        return "its readings checksum"
    return None


def autopilot_mismatch(rec: TickRecord, step: TeamStep) -> str | None:
    """On a tick whose driven robot's own driver chose the command (a team's autopilot
    tick), the replay's driver chooses again: what differs when its command is not the
    recorded ``u`` bit for bit (an edited command is never skipped), else None."""
    if not rec.autopilot or not 0 <= rec.driven < len(step.steps):
        return None
    chosen = step.steps[rec.driven].control
    if (chosen.v, chosen.omega) == (rec.control.v, rec.control.omega):
        return None
    return (f"robot {rec.driven}'s command u (its driver chose [{chosen.v!r}, {chosen.omega!r}] "
            f"again; the file says [{rec.control.v!r}, {rec.control.omega!r}])")


def recorded_controls(rec: TickRecord) -> dict[int, Control]:
    """The commands a recorded tick gives: the driven robot's (none on a team's autopilot
    tick: its driver chooses again), the others' drivers choose theirs."""
    return {} if rec.autopilot else {rec.driven: rec.control}


def replay_recording(recording: Recording, filters: list[str] | None = None,
                     params: dict[str, dict[str, Any]] | None = None,
                     verify: bool = True, *,
                     on_tick: Callable[[Any, TeamRunner], None] | None = None) -> RunResult:
    """Re-simulate a recording of any number of robots, feeding the filters; check the
    truth, the readings and (a version 3 file, the recorded filters) the filter settings
    and estimates against the file.

    ``filters`` None runs the recorded built-in filters with the recorded parameters
    (filters named by module or file path are skipped: pass them explicitly). Raises
    :class:`ReplayMismatch` naming the first tick (or line) and the field that differs.
    Returns what ``run`` gives on the recording's scenario, a
    :class:`~beacon_sim.runs.headless.RunResult` over its robots, with ``extra["replay"]``:
    what was checked (file, ticks, checksum status, skipped filters, warnings).
    ``on_tick(step, runner)`` is called after the filters took each tick (an export reads
    their beliefs there).
    """
    specs, skipped = recorded_filter_specs(recording, filters)
    used = recorded_params(recording, params)
    runner = TeamRunner(recording.team, specs, recording.seed, used,
                        step_limit_s=HEADLESS_STEP_LIMIT_S)
    verifier = replay_verifier(recording, runner, specs, used)
    if verify:
        why = verifier.check_settings()
        if why is not None:
            raise settings_error(recording, why)
    sim = TeamSimulation(recording.team, recording.seed)
    truth = ReplayedTruth(recording, sim)
    steps: list[TeamStep] = []
    checked = 0
    t0 = time.perf_counter()
    sim_ns = 0
    estimates = recording.parts.estimates
    unverified: str | None = None  # a file of unknown maths whose truth differs: why
    for rec in recording.ticks:
        a = time.perf_counter_ns()
        apply_to_run(rec.commands, sim, runner, HEADLESS_STEP_LIMIT_S, sim.time)
        step = sim.step(recorded_controls(rec))
        truth.observe(step)
        sim_ns += time.perf_counter_ns() - a
        if verify and unverified is None:
            why, bad = autopilot_mismatch(rec, step) or truth.tick_mismatch(rec), rec.tick
            cp = recording.checkpoints.get(rec.tick)
            if why is None and cp is not None and truth.state_differs(cp):
                why, bad = "the checkpoint", _first_bad_tick(recording, rec.tick)
            if why is not None:
                unverified = inputs_differ(recording, bad, rec.line, why)
            checked += tick_checked(recording, rec)
        steps.append(step)
        runner.feed(step)
        if on_tick is not None:
            on_tick(step, runner)
        if verify and unverified is None:
            line = estimates.get(rec.tick)
            verifier.fold(rec.tick)
            why = verifier.compare_line(rec.tick, line)
            if why is not None:
                raise mismatch_error(recording, rec.tick, line["line"] if line else rec.line, why)
    wall = time.perf_counter() - t0
    end = recording.end
    if verify and unverified is None and end is not None \
            and (end.get("ticks") != sim.tick or truth.state_differs(end)):
        unverified = inputs_differ(recording, sim.tick, len(recording.ticks), "the final checksum")
    if verify and unverified is None and end is not None and "estimates" in end:
        why = verifier.compare_line(sim.tick, end_estimates(end))
        if why is not None:
            raise mismatch_error(recording, sim.tick, len(recording.ticks), why + " at the end")
    status = unverified or verification_status(recording, checked, len(recording.ticks),
                                               at_end=True, coverage=verifier.coverage())
    replay = {
        "file": str(recording.path), "ticks": len(recording.ticks), "complete": recording.complete,
        "checksum_status": with_signature(status, recording) if verify else "not checked",
        "recorded_checksum": end["checksum"] if end else None,
        "skipped_filters": skipped, "warnings": list(recording.warnings),
        "maths": verifier.maths.as_json(),
        "estimate_differences": {n: d.as_json() for n, d in sorted(verifier.differences.items())},
    }
    out = RunResult(recording.team, recording.seed, steps, runner, wall, sim_ns / 1e9, truth.truth)
    out.extra["replay"] = replay
    return out


def end_estimates(end: dict[str, Any]) -> dict[str, Any]:
    """The end line's digests, notes and values, in an estimates line's keys."""
    return {"digests": end["estimates"], "notes": end.get("notes", {}),
            "values": end.get("values", {})}


def inputs_differ(recording: Recording, tick: int, line: int, what: str) -> str:
    """A replay whose truth or readings differ from the recording at ``tick`` (file line
    ``line``, checked against ``what``): a file that names the maths that made it was edited
    (the truth and readings are the same bits on every machine): ReplayMismatch; one made
    before (format version 3 and older) cannot be told apart from the maths changed since:
    the status that says so (the replay goes on, not verified)."""
    if recording.maths is not None:
        raise mismatch_error(recording, tick, line, what)
    return old_maths_text(tick, recording.scenario.dt, what)


def tick_checked(recording: Recording, rec: TickRecord) -> int:
    """1 when the tick carries every checksum its format version has (truth; version 2 also
    readings), else 0."""
    return int(rec.short_checksum is not None
               and (recording.version < 2 or rec.readings_checksum is not None))


def verification_status(recording: Recording, checked: int, ticks: int, at_end: bool,
                        coverage: tuple[list[str], str, str] | None = None) -> str:
    """What a replay may claim, in words (docs/replay.md, "What replay verifies"). The end
    line's checksums cover every tick; without it only the ticks that carry checksums count.
    ``coverage`` (:meth:`FilterVerifier.coverage`) lists what could not be compared: then
    the status begins "not verified: <what>" and says what was. "verified" alone means
    truth, readings, the commands, filter settings and estimates all matched."""
    gaps, what, note = coverage or FilterVerifier(recording, None, False, []).coverage()
    missing = "; ".join(gaps)
    if not ticks and not at_end:
        return "nothing checked yet (no tick replayed)"
    end = recording.end
    if at_end and end is not None and (recording.version < 2 or "readings_checksum" in end):
        level = "verified"
    elif ticks and checked == ticks:
        level = "verified up to the last complete tick"
    elif checked or (end is not None and at_end):
        return (f"partly verified: {checked} of {ticks} ticks carry checksums"
                + (f"; not verified: {missing}" if gaps else "") + note)
    else:
        return "not verified: the recording holds no checksums"
    if gaps:
        return f"not verified: {missing}; {what} {level}{note}"
    return level + note


def _first_bad_tick(recording: Recording, tick: int) -> int:
    prev = [k for k in recording.checkpoints if k < tick]
    return (max(prev) + 1) if prev else 1


def mismatch_error(recording: Recording, tick: int, line: int,
                   what: str) -> ReplayMismatch:
    """The error of a replay that differs from its recording at ``tick`` (file line ``line``),
    checked against ``what``."""
    return ReplayMismatch(
        f"{recording.path}:{line}: replay differs from the recording at tick {tick} "
        f"(t = {tick * recording.scenario.dt:g} s; checked against {what}): was it edited, or "
        f"recorded by another version of beacon-sim (recorded by "
        f"{recording.header.get('program_version')})?")


def replay_label(path: Path) -> str:
    """What the panel says drives a replay: ``replay`` and the file's name, shortened in the
    middle past 28 characters."""
    name = path.name
    return "replay " + (name if len(name) <= 28 else name[:12] + "..." + name[-13:])


class ReplaySession(Session):
    """A :class:`~beacon_sim.runs.live.Session` whose driven robot, commands and user
    commands come from a recording of any number of robots, one tick at a time (the replay
    window's scene, with the timeline's ``total_ticks``, ``at_end``, ``marks`` and
    ``seek``). Each tick is checked as :func:`replay_recording` checks it; ``mismatch`` holds
    the first difference (naming the field), ``checksum_status()`` what was verified."""

    #: The panel shows who was driven, without the Tab hint (keys do not drive a replay).
    replaying = True

    def __init__(self, recording: Recording, specs: list[str],
                 params: dict[str, dict[str, Any]] | None = None):
        self.recording = recording
        super().__init__(recording.team, list(specs), recording.seed, dict(params or {}))
        self._fresh()

    def _fresh(self) -> None:
        """The checks from tick 0, for the simulation and the filters just built."""
        self.mismatch: str | None = None  # the first difference from the file (names the field)
        # a file that does not name its maths whose truth differs: why it is not verified
        self.unverified: str | None = None
        self._checked = 0  # ticks so far that carried their checksums
        self.truth = ReplayedTruth(self.recording, self.sim)
        self._apply_recorded_driving()
        self.verifier = replay_verifier(self.recording, self.filters_run, self.specs, self.params)
        why = self.verifier.check_settings()
        if why is not None:
            self.mismatch = f"{self.recording.path}:{self.recording.parts.settings_line}: {why}"
        elif self.recording.parts.signature_error:
            self.mismatch = self.recording.parts.signature_error

    def _apply_recorded_driving(self) -> None:
        """Who the next recorded tick drives (the panel shows it)."""
        ticks = self.recording.ticks
        if ticks:
            rec = ticks[min(self.sim.tick, len(ticks) - 1)]
            self.driven, self.autopilot = rec.driven, rec.autopilot

    @property
    def total_ticks(self) -> int:
        return len(self.recording.ticks)

    @property
    def at_end(self) -> bool:
        return self.sim.tick >= self.total_ticks

    def marks(self) -> list[tuple[int, str]]:
        """(tick, kind of the first user command) of the recorded user commands."""
        return [(rec.tick, rec.commands[0]["kind"]) for rec in self.recording.ticks if rec.commands]

    @property
    def drive_mode(self) -> str:
        return replay_label(self.recording.path)

    def next_control(self) -> Control:
        """The driven robot's recorded command of the next tick (its driver's where it chose
        on a team's file; the last one once the recording ends)."""
        ticks = self.recording.ticks
        if not ticks:
            return Control()
        rec = ticks[min(self.sim.tick, len(ticks) - 1)]
        if rec.autopilot and not self.at_end:
            return super().next_control()
        return rec.control

    def seek(self, tick: int, keep_flips: Set[str] = frozenset()) -> None:
        """Show the run at ``tick``: forward by running the ticks in between, backward by
        restarting (a fresh simulation, fresh filters, empty trails) and re-simulating from
        the start (the recording holds no generator state). ``keep_flips``: filters the user
        showed / hid, flipped again after a restart."""
        tick = min(max(int(tick), 0), self.total_ticks)
        if tick < self.sim.tick:
            self.close()
            self.restart()
            self._fresh()
            for name in keep_flips:
                if name in self.visible:
                    self.visible[name] = not self.visible[name]
        while self.sim.tick < tick:
            self.tick()

    def tick(self) -> TeamStep:
        """The next recorded tick: its commands, the driven robot's command, then the
        checksum check."""
        rec = self.recording.ticks[self.sim.tick]
        self.driven, self.autopilot = rec.driven, rec.autopilot
        self.pending = [dict(c) for c in rec.commands if c["kind"] != "toggle"]
        for c in rec.commands:  # recorded show / hide of a filter (display only)
            if c["kind"] == "toggle" and c.get("filter") in self.visible:
                self.visible[c["filter"]] = not self.visible[c["filter"]]
        step = super().tick()
        self.truth.observe(step)
        self.verifier.fold(rec.tick)
        if self.mismatch is None and self.unverified is None:
            self._check(rec, step)
        self._apply_recorded_driving()
        return step

    def _check(self, rec: TickRecord, step: TeamStep) -> None:
        """The tick's checksums and estimates against the file (as :func:`replay_recording`):
        a difference is a mismatch, or on a file that does not name its maths whose truth
        differs, the reason it is not verified."""
        line = self.recording.parts.estimates.get(rec.tick)
        why = autopilot_mismatch(rec, step) or self.truth.tick_mismatch(rec)
        if why is not None and self.recording.maths is None:
            self.unverified = old_maths_text(rec.tick, self.scenario.dt, why)
            return
        why = why or self.verifier.compare_line(rec.tick, line)
        if why is not None:
            self.mismatch = (f"{self.recording.path}:{line['line'] if line else rec.line}: "
                             f"replay differs from the recording at tick {rec.tick} "
                             f"(t = {self.sim.time:g} s; {why})")
        self._checked += tick_checked(self.recording, rec)

    def checksum_status(self) -> str:
        """"verified", "MISMATCH ...", or how far the check went."""
        return session_status(self, self.truth.truth, self.truth.readings)


def session_status(session: ReplaySession, truth: str, readings: str) -> str:
    """A replay window's status: "MISMATCH: ..." naming the field, or what was verified so
    far (the end line's checksums and estimates once at the end)."""
    if session.mismatch:
        return f"MISMATCH: {session.mismatch}"
    rec = session.recording
    end = rec.end
    if session.at_end and end is not None and session.unverified is None:
        if end["checksum"] != truth or end.get("readings_checksum", readings) != readings:
            if rec.maths is None:
                session.unverified = old_maths_text(session.sim.tick, rec.scenario.dt,
                                                    "the final checksum")
            else:
                session.mismatch = (f"{rec.path}: replay differs from the recording at its end "
                                    f"(checked against the final checksum)")
                return f"MISMATCH: {session.mismatch}"
        elif "estimates" in end:
            why = session.verifier.compare_line(session.sim.tick, end_estimates(end))
            if why is not None:
                session.mismatch = f"{rec.path}: the end line: {why}"
                return f"MISMATCH: {session.mismatch}"
    status = session.unverified or verification_status(
        rec, session._checked, session.sim.tick, session.at_end,
        coverage=session.verifier.coverage())
    try:
        status = with_signature(status, rec)
    except ReplayMismatch as exc:
        session.mismatch = str(exc)
        return f"MISMATCH: {session.mismatch}"
    return status if session.at_end else f"{status} (up to tick {session.sim.tick})"
