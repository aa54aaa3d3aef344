"""Replaying a recording bit for bit, with the recorded filters or any others.

The one home of "how a recording is replayed": :func:`replay_recording` re-simulates a
file headless and checks its checksums; :class:`ReplaySession` is the same, one tick at a
time, for the window. The file format is beacon_sim/io/recording.py (and docs/replay.md).
"""

from __future__ import annotations

import time
from collections.abc import Set
from pathlib import Path
from typing import Any

from beacon_sim.core.simulation import Simulation
from beacon_sim.core.types import Control, Step
from beacon_sim.filters.base import Filter
from beacon_sim.filters.loading import build_filters as build_all
from beacon_sim.filters.runner import HEADLESS_STEP_LIMIT_S, FilterRunner
from beacon_sim.io.recording import Recording, RecordingError, TickRecord
from beacon_sim.runs.headless import RunResult
from beacon_sim.runs.live import Session
from beacon_sim.runs.user_commands import apply_commands


class ReplayMismatch(RecordingError):
    """The replayed truth differs from the recorded one."""


def _is_safe_spec(spec: str) -> bool:
    """Built-in filters (and installed entry points) only: a recording never makes us
    import a module or a file it names."""
    return ":" not in spec


def recorded_filter_specs(recording: Recording, requested: list[str] | None) -> tuple[list[str], list[str]]:
    """(filters to run, recorded filters skipped): ``requested`` when given (even empty);
    otherwise the recorded built-in ones (named by module or file path: skipped)."""
    if requested is not None:
        return list(requested), []
    return ([s for s in recording.filters if _is_safe_spec(s)],
            [s for s in recording.filters if not _is_safe_spec(s)])


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


def build_filters(specs: list[str], recording: Recording,
                  params: dict[str, dict[str, Any]] | None = None
                  ) -> tuple[dict[str, Filter | None], dict[str, tuple[str, str]]]:
    """Construct the filters for a replay, named as a headless run names them: (name ->
    filter or None, name -> (why construction failed, traceback))."""
    return build_all(specs, recording.scenario, recording.seed, params)


def replay_recording(recording: Recording, filters: list[str] | None = None,
                     params: dict[str, dict[str, Any]] | None = None,
                     verify: bool = True) -> RunResult:
    """Re-simulate a recording, feeding the filters; check the truth against the file.

    ``filters`` None runs the recorded built-in filters with the recorded parameters
    (filters named by module or file path are skipped: pass them explicitly). Raises
    :class:`ReplayMismatch` naming the first tick whose truth differs.
    """
    specs, skipped = recorded_filter_specs(recording, filters)
    built, broken = build_filters(specs, recording, recorded_params(recording, params))
    runner = FilterRunner(built, step_limit_s=HEADLESS_STEP_LIMIT_S)
    for name, (why, tb) in broken.items():
        runner.tracks[name].failed, runner.tracks[name].traceback = why, tb
    scenario = recording.scenario
    sim = Simulation(scenario, recording.seed)
    steps: list[Step] = []
    checked = 0
    t0 = time.perf_counter()
    sim_ns = 0
    for rec in recording.ticks:
        a = time.perf_counter_ns()
        if rec.commands:
            working = {n: t.filter for n, t in runner.tracks.items() if t.filter and not t.failed}
            for name, (why, tb) in apply_commands(rec.commands, sim, working, scenario).items():
                runner.fail(name, why, tb, sim.time)
        step = sim.step(rec.control)
        sim_ns += time.perf_counter_ns() - a
        if verify:
            why = tick_mismatch(recording, rec, sim)
            if why is not None:
                raise mismatch_error(recording, rec.tick, rec.line, why)
            checked += tick_checked(recording, rec)
            cp = recording.checkpoints.get(rec.tick)
            if cp is not None and (cp["checksum"] != sim.truth_checksum
                                   or cp.get("pose") != [float(v) for v in sim.pose]
                                   or cp.get("readings_checksum", sim.readings_checksum)
                                   != sim.readings_checksum):
                raise mismatch_error(recording, _first_bad_tick(recording, rec.tick), rec.line,
                                "the checkpoint")
        steps.append(step)
        runner.feed(step)
    wall = time.perf_counter() - t0
    end = recording.end
    if verify and end is not None and (
            end.get("ticks") != sim.tick or end["checksum"] != sim.truth_checksum
            or end.get("readings_checksum", sim.readings_checksum) != sim.readings_checksum):
        raise mismatch_error(recording, sim.tick, len(recording.ticks), "the final checksum")
    status = verification_status(recording, checked, len(recording.ticks), at_end=True)
    result = RunResult(scenario, recording.seed, steps, runner, wall, sim_ns / 1e9, sim.truth_checksum)
    result.extra["replay"] = {
        "file": str(recording.path), "ticks": len(recording.ticks), "complete": recording.complete,
        "checksum_status": status if verify else "not checked",
        "recorded_checksum": end["checksum"] if end else None,
        "skipped_filters": skipped, "warnings": list(recording.warnings),
    }
    return result


def tick_mismatch(recording: Recording, rec: TickRecord, sim: Simulation) -> str | None:
    """What the tick's recorded checksums disagree with after ``sim`` ran it, or None."""
    if rec.short_checksum is not None and sim.truth_checksum[:8] != rec.short_checksum:
        return "its truth checksum"
    if rec.readings_checksum is not None and sim.readings_checksum[:8] != rec.readings_checksum:
        return "its readings checksum"
    return None


def tick_checked(recording: Recording, rec: TickRecord) -> int:
    """1 when the tick carries every checksum its format version has (truth; version 2 also
    readings), else 0."""
    return int(rec.short_checksum is not None
               and (recording.version < 2 or rec.readings_checksum is not None))


def verification_status(recording: Recording, checked: int, ticks: int, at_end: bool) -> str:
    """What a replay may claim, in words (docs/replay.md, "What replay verifies"). The end
    line's checksums cover every tick; without it only the ticks that carry checksums count.
    Version 1 files cover the truth only."""
    covers = "" if recording.version >= 2 else \
        " (truth only: a version 1 file does not cover the readings and the scenario)"
    end = recording.end
    if at_end and end is not None and (recording.version < 2 or "readings_checksum" in end):
        return "verified" + covers
    if ticks and checked == ticks:
        return "verified up to the last complete tick" + covers
    if checked or (end is not None and at_end):
        return f"partly verified: {checked} of {ticks} ticks carry checksums" + covers
    return "not verified: the recording holds no checksums"


def _first_bad_tick(recording: Recording, tick: int) -> int:
    prev = [k for k in recording.checkpoints if k < tick]
    return (max(prev) + 1) if prev else 1


def mismatch_error(recording: Recording, tick: int, line: int, what: str) -> ReplayMismatch:
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
    """A :class:`~beacon_sim.runs.live.Session` whose controls and user commands come from a
    recording, one tick at a time (the replay window's scene)."""

    def __init__(self, recording: Recording, specs: list[str],
                 params: dict[str, dict[str, Any]] | None = None):
        self.recording = recording
        self.mismatch: str | None = None  # first tick whose truth differs from the file
        self._checked = 0  # ticks so far that carried their checksums
        super().__init__(recording.scenario, list(specs), recording.seed, dict(params or {}))

    @property
    def total_ticks(self) -> int:
        return len(self.recording.ticks)

    def marks(self) -> list[tuple[int, str]]:
        """(tick, kind of the first user command) of the recorded user commands."""
        return [(rec.tick, rec.commands[0]["kind"]) for rec in self.recording.ticks if rec.commands]

    @property
    def at_end(self) -> bool:
        return self.sim.tick >= self.total_ticks

    @property
    def drive_mode(self) -> str:
        return replay_label(self.recording.path)

    def next_control(self) -> Control:
        """The recorded control of the next tick (the last one once the recording ends)."""
        ticks = self.recording.ticks
        if not ticks:
            return Control()
        return ticks[min(self.sim.tick, len(ticks) - 1)].control

    def seek(self, tick: int, keep_flips: Set[str] = frozenset()) -> None:
        """Show the run at ``tick``: forward by running the ticks in between, backward by
        rebuilding the simulation and the filters and re-simulating from the start (the
        recording holds no generator state). ``keep_flips``: filters the user showed / hid,
        flipped again after a rebuild."""
        tick = min(max(int(tick), 0), self.total_ticks)
        if tick < self.sim.tick:
            self.close()
            self.mismatch = None
            self._checked = 0
            self.__post_init__()  # a fresh simulation, fresh filters, empty trails
            for name in keep_flips:
                if name in self.visible:
                    self.visible[name] = not self.visible[name]
        while self.sim.tick < tick:
            self.tick()

    def tick(self) -> Step:
        """The next recorded tick: its commands, its control, then the checksum check."""
        rec = self.recording.ticks[self.sim.tick]
        self.pending = [dict(c) for c in rec.commands]
        for c in self.pending:  # recorded show / hide of a filter (display only)
            if c["kind"] == "toggle" and c.get("filter") in self.visible:
                self.visible[c["filter"]] = not self.visible[c["filter"]]
        step = super().tick()
        if self.mismatch is None:
            why = tick_mismatch(self.recording, rec, self.sim)
            if why is not None:
                self.mismatch = (f"{self.recording.path}:{rec.line}: replay differs from the "
                                 f"recording at tick {rec.tick} (t = {self.sim.time:g} s; {why})")
            self._checked += tick_checked(self.recording, rec)
        return step

    def checksum_status(self) -> str:
        """"verified", "MISMATCH ...", or how far the check went."""
        if self.mismatch:
            return f"MISMATCH: {self.mismatch}"
        end = self.recording.end
        if self.at_end and end is not None and (
                end["checksum"] != self.sim.truth_checksum
                or end.get("readings_checksum", self.sim.readings_checksum) != self.sim.readings_checksum):
            return "MISMATCH with the end line's checksum"
        status = verification_status(self.recording, self._checked, self.sim.tick, self.at_end)
        return status if self.at_end else f"{status} (up to tick {self.sim.tick})"
