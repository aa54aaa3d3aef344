"""Replaying a team session's recording bit for bit, with the recorded team filters or any
others (the team counterpart of runs/replay.py; the format is beacon_sim/io/recording.py,
``kind: "team"``).

:func:`replay_team_recording` re-simulates a file headless, checks its checksums (truth and
readings, per tick, at the checkpoints and at the end) and gives the figures of
``beacon-sim run`` on a team scenario (a :class:`~beacon_sim.runs.headless.RunResult`);
:class:`TeamReplaySession` is the same one tick at a time, for the window.

Each tick goes as it went live (``runs/live.Session.tick``): the recorded user
commands (a kidnap of the robot it names, a reset of every team filter), then every robot
steps, the recorded driven robot with its recorded command (or, where its own driver chose
it live, the driver again, so that the driver's state follows), the others on their
drivers; then the team filters are fed.

A recording names team filters as ``run`` takes them; only built-in ones are run from a
file (:func:`is_builtin_team_spec`): a recording never makes beacon-sim import code.
"""

from __future__ import annotations

import time
from collections.abc import Set
from dataclasses import dataclass
from typing import Any

from beacon_sim.core.team import TeamSimulation, TeamStep
from beacon_sim.core.types import Control
from beacon_sim.filters.loading import split_label
from beacon_sim.filters.runner import HEADLESS_STEP_LIMIT_S, FilterRunner
from beacon_sim.filters.team_runner import JointRunner, TeamRunner, build_team_filters
from beacon_sim.filters.team_specs import MEMBER_PREFIX, build_team_spec, team_filter_name
from beacon_sim.io.recording import TeamRecording, TeamTickRecord
from beacon_sim.runs.headless import RunResult
from beacon_sim.runs.live import Session, TeamTracks, reset_team_filters
from beacon_sim.runs.recorder import TeamReadingsHash, team_commands_to_sim
from beacon_sim.runs.replay import (
    FilterVerifier,
    ReplayMismatch,
    mismatch_error,
    recorded_params,
    replay_label,
    session_status,
    settings_compared,
    settings_error,
    tick_checked,
    verification_status,
    with_signature,
)


def is_builtin_team_spec(spec: str) -> bool:
    """A team filter spec a recording may run: a team filter by name, or ``independent:F``
    with F a built-in filter or an entry point (optionally labelled). Anything naming a
    module or a file (``my_team.py:MyTeam``, ``independent:alice.py:MyEkf``) is not."""
    _, body = split_label(spec)
    if body.startswith(MEMBER_PREFIX):
        body = body[len(MEMBER_PREFIX):]
    return bool(body) and ":" not in body and "/" not in body and "\\" not in body \
        and not body.endswith(".py")


def recorded_team_specs(recording: TeamRecording,
                        requested: list[str] | None) -> tuple[list[str], list[str]]:
    """(team filters to run, recorded ones skipped): ``requested`` when given; otherwise
    the recorded built-in ones (those naming a module or a file are skipped: pass them with
    ``--filter``)."""
    if requested is not None:
        return list(requested), []
    return ([s for s in recording.filters if is_builtin_team_spec(s)],
            [s for s in recording.filters if not is_builtin_team_spec(s)])


def team_tick_mismatch(rec: TeamTickRecord, truth: str, readings: str) -> str | None:
    """What the tick's recorded checksums disagree with (the team's truth and readings
    checksums after the tick), or None."""
    if rec.short_checksum is not None and truth[:8] != rec.short_checksum:
        return "its truth checksum"
    if rec.readings_checksum is not None and readings[:8] != rec.readings_checksum:
        return "its readings checksum"
    return None


def step_recorded(sim: TeamSimulation, rec: TeamTickRecord) -> TeamStep:
    """One recorded tick of the truth: the kidnaps it holds, then every robot's step (the
    driven one on its recorded command, or on its own driver where the driver chose live)."""
    team_commands_to_sim(rec.commands, sim)
    return sim.step({} if rec.autopilot else {rec.driven: rec.control})


@dataclass
class TeamReplayResult:
    """A team recording replayed: the run's figures (``result.as_json()`` as ``run``
    prints them) and what the replay checked (``replay``: file, ticks, checksum status,
    skipped filters, warnings)."""

    result: RunResult
    replay: dict[str, Any]
    readings_checksum: str

    def as_json(self) -> dict[str, Any]:
        return {**self.result.as_json(), "replay": self.replay}


def _build_runner(recording: TeamRecording, specs: list[str],
                  params: dict[str, dict[str, Any]]) -> JointRunner:
    team = recording.team
    by_name = {team_filter_name(s): s for s in specs}
    built, why = build_team_filters(
        list(by_name), lambda n: build_team_spec(by_name[n], team, params.get(n), recording.seed),
        HEADLESS_STEP_LIMIT_S)
    runner = JointRunner(built, len(team.robots), HEADLESS_STEP_LIMIT_S)
    for name, reason in why.items():
        runner.tracks[name].failed = f"could not be built: {reason}"
    return runner


def replay_team_recording(recording: TeamRecording, filters: list[str] | None = None,
                          params: dict[str, dict[str, Any]] | None = None,
                          verify: bool = True) -> TeamReplayResult:
    """Re-simulate a team recording, feeding the team filters; check truth and readings
    against the file. ``filters`` None runs the recorded built-in team filters with the
    recorded parameters (``params``, from ``--set``, on top). Raises
    :class:`~beacon_sim.runs.replay.ReplayMismatch` naming the first tick that differs."""
    specs, skipped = recorded_team_specs(recording, filters)
    used = recorded_params(recording, params)
    runner = _build_runner(recording, specs, used)
    verifier = team_verifier(recording, runner, specs, used)
    if verify:
        why = verifier.check_settings()
        if why is not None:
            raise settings_error(recording, why)
    team = recording.team
    sim = TeamSimulation(team, recording.seed)
    readings = TeamReadingsHash()
    steps: list[TeamStep] = []
    checked = 0
    t0 = time.perf_counter()
    for rec in recording.ticks:
        if any(c["kind"] == "reset" for c in rec.commands):
            reset_team_filters(runner, team, HEADLESS_STEP_LIMIT_S, sim.time)
        step = step_recorded(sim, rec)
        readings.update(step)
        if verify:
            why = team_tick_mismatch(rec, sim.truth_checksum, readings.checksum)
            if why is not None:
                raise mismatch_error(recording, rec.tick, rec.line, why)
            checked += tick_checked(recording, rec)
            cp = recording.checkpoints.get(rec.tick)
            if cp is not None and (cp["checksum"] != sim.truth_checksum
                                   or cp["poses"] != sim.poses.tolist()
                                   or cp.get("readings_checksum", readings.checksum)
                                   != readings.checksum):
                prev = [k for k in recording.checkpoints if k < rec.tick]
                raise mismatch_error(recording, (max(prev) + 1) if prev else 1, rec.line,
                                "the checkpoint")
        steps.append(step)
        runner.feed(step.tick, step.time, [s.control for s in step.steps], step.dt,
                    [step.measurements(i) for i in range(len(step.steps))])
        if verify:
            line = recording.parts.estimates.get(rec.tick)
            verifier.fold(rec.tick)
            why = verifier.compare_line(rec.tick, line)
            if why is not None:
                raise mismatch_error(recording, rec.tick, line["line"] if line else rec.line, why)
    wall = time.perf_counter() - t0
    end = recording.end
    if verify and end is not None and (
            end.get("ticks") != sim.tick or end["checksum"] != sim.truth_checksum
            or end.get("readings_checksum", readings.checksum) != readings.checksum
            or end["poses"] != sim.poses.tolist()):
        raise mismatch_error(recording, sim.tick, len(recording.ticks), "the final checksum")
    if verify and end is not None and "estimates" in end:
        why = verifier.compare_line(sim.tick, {"digests": end["estimates"],
                                               "notes": end.get("notes", {})})
        if why is not None:
            raise mismatch_error(recording, sim.tick, len(recording.ticks), why + " at the end")
    status = verification_status(recording, checked, len(recording.ticks), at_end=True,
                                 coverage=verifier.coverage())
    result = RunResult(team, recording.seed, steps,
                       TeamRunner.around(team, [FilterRunner({}) for _ in team.robots], runner),
                       wall, wall, sim.truth_checksum)
    replay = {
        "file": str(recording.path), "ticks": len(recording.ticks), "complete": recording.complete,
        "checksum_status": with_signature(status, recording) if verify else "not checked",
        "recorded_checksum": end["checksum"] if end else None,
        "skipped_filters": skipped, "warnings": list(recording.warnings),
    }
    return TeamReplayResult(result, replay, readings.checksum)


def team_verifier(recording: TeamRecording, runner: JointRunner | TeamTracks, specs: list[str],
                  used: dict[str, dict[str, Any]]) -> FilterVerifier:
    """The filter settings and estimates check of a team replay (runs/replay.FilterVerifier;
    ``used``: the parameters the replay built the team filters with)."""
    recorded, skipped = recorded_team_specs(recording, None)
    return FilterVerifier(recording, runner.tracks,
                          settings_compared(recording, specs, recorded, used),
                          [team_filter_name(s) for s in skipped])


class TeamReplaySession(Session):
    """A :class:`~beacon_sim.runs.live.Session` whose driven robot, commands and
    user commands come from a team recording, one tick at a time (the replay window's
    scene: the timeline methods of ``runs/replay.ReplaySession``)."""

    #: The panel shows who was driven, without the Tab hint (keys do not drive a replay).
    replaying = True

    def __init__(self, recording: TeamRecording, specs: list[str],
                 params: dict[str, dict[str, Any]] | None = None):
        self.recording = recording
        super().__init__(recording.team, list(specs), recording.seed, dict(params or {}))
        self._fresh()

    def _fresh(self) -> None:
        self.mismatch: str | None = None  # the first difference from the file (names the field)
        self._checked = 0
        self._readings_hash = TeamReadingsHash()
        self._apply_recorded_driving()
        self.verifier = team_verifier(self.recording, TeamTracks(self.filters_run), self.specs,
                                      self.params)
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
        """The driven robot's recorded command of the next tick (its driver's where it chose)."""
        ticks = self.recording.ticks
        if not ticks:
            return Control()
        rec = ticks[min(self.sim.tick, len(ticks) - 1)]
        if rec.autopilot and not self.at_end:
            return super().next_control()
        return rec.control

    def seek(self, tick: int, keep_flips: Set[str] = frozenset()) -> None:
        """Show the run at ``tick``: forward by running the ticks in between, backward by
        rebuilding the simulation and the filters and re-simulating from the start."""
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
        self._readings_hash.update(step)
        self.verifier.fold(rec.tick)
        if self.mismatch is None:
            line = self.recording.parts.estimates.get(rec.tick)
            why = team_tick_mismatch(rec, self.sim.truth_checksum, self._readings_hash.checksum) \
                or self.verifier.compare_line(rec.tick, line)
            if why is not None:
                self.mismatch = (f"{self.recording.path}:{line['line'] if line else rec.line}: "
                                 f"replay differs from the recording at tick {rec.tick} "
                                 f"(t = {self.sim.time:g} s; {why})")
            self._checked += tick_checked(self.recording, rec)
        self._apply_recorded_driving()
        return step

    def checksum_status(self) -> str:
        """"verified", "MISMATCH ...", or how far the check went."""
        return session_status(self, self.sim.truth_checksum, self._readings_hash.checksum)


__all__ = ["ReplayMismatch", "TeamReplayResult", "TeamReplaySession", "is_builtin_team_spec",
           "recorded_team_specs", "replay_team_recording"]
