"""Replaying a team session's recording bit for bit, with the recorded team filters or any
others (the team counterpart of runs/replay.py; the format is beacon_sim/io/recording.py,
``kind: "team"``).

:func:`replay_team_recording` re-simulates a file headless, checks its checksums (truth and
readings, per tick, at the checkpoints and at the end) and gives the figures of
``beacon-sim run`` on a team scenario (a :class:`~beacon_sim.runs.team.TeamRunResult`);
:class:`TeamReplaySession` is the same one tick at a time, for the window.

Each tick goes as it went live (``runs/team_live.TeamSession.tick``): the recorded user
commands (a kidnap of the robot it names, a reset of every team filter), then every robot
steps, the recorded driven robot with its recorded command (or, where its own driver chose
it live, the driver again, so that the driver's state follows), the others on their
drivers; then the team filters are fed.

A recording names team filters as ``run`` takes them; only built-in ones are run from a
file (:func:`is_builtin_team_spec`): a recording never makes beacon-sim import code.
"""

from __future__ import annotations

from collections.abc import Set
from typing import Any

from beacon_sim.core.team import TeamStep
from beacon_sim.core.types import Control
from beacon_sim.io.recording import Recording
from beacon_sim.runs.recorder import TeamReadingsHash
from beacon_sim.runs.replay import (
    FilterVerifier,
    checksums_mismatch,
    replay_label,
    replay_verifier,
    session_status,
    tick_checked,
)
from beacon_sim.runs.team_live import TeamSession


def team_verifier(recording: Recording, runner: Any, specs: list[str],
                  used: dict[str, dict[str, Any]]) -> FilterVerifier:
    return replay_verifier(recording, runner, specs, used)


class TeamReplaySession(TeamSession):
    """A :class:`~beacon_sim.runs.team_live.TeamSession` whose driven robot, commands and
    user commands come from a team recording, one tick at a time (the replay window's
    scene: the timeline methods of ``runs/replay.ReplaySession``)."""

    #: The panel shows who was driven, without the Tab hint (keys do not drive a replay).
    replaying = True

    def __init__(self, recording: Recording, specs: list[str],
                 params: dict[str, dict[str, Any]] | None = None):
        self.recording = recording
        super().__init__(recording.team, list(specs), recording.seed, dict(params or {}))
        self._fresh()

    def _fresh(self) -> None:
        self.mismatch: str | None = None  # the first difference from the file (names the field)
        self._checked = 0
        self._readings_hash = TeamReadingsHash()
        self._apply_recorded_driving()
        self.verifier = team_verifier(self.recording, self.runner, self.specs, self.params)
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
            self.__post_init__()
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
            why = checksums_mismatch(rec, self.sim.truth_checksum, self._readings_hash.checksum) \
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


__all__ = ["TeamReplaySession"]
