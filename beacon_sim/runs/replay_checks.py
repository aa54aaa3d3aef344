"""A replayed tick checked against its recording: the truth's and readings' checksums, the
autopilot's commands, the recorded user inputs; the first bad tick and the one-line error;
the verification status (with the file's signature) a replay ends with."""

from __future__ import annotations

from typing import Any

from beacon_sim.core.team import TeamSimulation, TeamStep
from beacon_sim.core.types import Control
from beacon_sim.io.recording import (
    Recording,
    TickRecord,
    recording_key,
)
from beacon_sim.runs.recorder import TeamReadingsHash
from beacon_sim.runs.replay_filters import (
    FilterVerifier,
    ReplayMismatch,
)
from beacon_sim.runs.replay_maths import old_maths_text


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


def first_bad_tick(recording: Recording, tick: int) -> int:
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


__all__ = [
    "ReplayedTruth",
    "autopilot_mismatch",
    "checksums_mismatch",
    "end_estimates",
    "first_bad_tick",
    "inputs_differ",
    "mismatch_error",
    "recorded_controls",
    "tick_checked",
    "verification_status",
    "with_signature",
]
