"""A recording replayed one tick at a time for the window (``ReplaySession``: seek, the
recorded driving, the checks as it goes) and its status line."""

from __future__ import annotations

from collections.abc import Set
from pathlib import Path
from typing import Any

from beacon_sim.core.team import TeamStep
from beacon_sim.core.types import Control
from beacon_sim.io.recording import (
    Recording,
    TickRecord,
)
from beacon_sim.runs.live import Session
from beacon_sim.runs.replay_checks import (
    ReplayedTruth,
    autopilot_mismatch,
    end_estimates,
    tick_checked,
    verification_status,
    with_signature,
)
from beacon_sim.runs.replay_filters import (
    ReplayMismatch,
    replay_verifier,
)
from beacon_sim.runs.replay_maths import old_maths_text


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


__all__ = ["ReplaySession", "replay_label", "session_status"]
