"""Writing a recording while a run goes, of any number of robots (the format is
beacon_sim/io/recording.py).

The one writer, :class:`Recorder`, re-simulates alongside the caller (a shadow
:class:`~beacon_sim.core.team.TeamSimulation` from the same scenario and seed, given the
same commands), so the file carries its own checksums whatever the caller passes. A team
of one (a single robot) is written in a single robot's format, byte for byte as before
0.3.0; a team in a team's (the driven robot's index and command per tick). Lines are
flushed at least every half second of simulated or wall time: a killed program leaves a
file that replays to within a second of the kill. The header names the maths of the machine
that records and the scenario without a folder; the estimates lines hold the
filters' estimates beside their digests, so a replay on other maths compares them within a
tolerance (beacon_sim/runs/replay_maths.py).
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import hashlib
import time
import warnings
from dataclasses import replace
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from beacon_sim.core.maths_fingerprint import maths_description, maths_fingerprint
from beacon_sim.core.scenario import Scenario, TeamScenario, as_team, team_of_one
from beacon_sim.core.simulation import CURRENT_SLIP_MODEL
from beacon_sim.core.team import TeamSimulation, TeamStep
from beacon_sim.core.types import Control
from beacon_sim.io.recording import (
    FLUSH_EVERY_S,
    FORMAT_NAME,
    FORMAT_VERSION,
    TEAM_KIND,
    EstimateDigests,
    RecordingError,
    Signer,
    dumps,
    effective_params,
    map_file_name,
    map_header,
    open_exclusive,
    rebuild_scenario,
    rebuild_team_scenario,
    recorded_tracks,
    recording_key,
    scenario_label,
    scenario_text,
    text_checksum,
    validate_command,
)
from beacon_sim.runs.user_commands import apply_commands
from beacon_sim.version import __version__


class Recorder:
    """Writes one run of any number of robots to ``path`` as it goes.

    Parameters
    ----------
    path : str or Path
        The ``.jsonl`` file to create (its folder is created too).
    scenario : Scenario or TeamScenario
        Loaded from a TOML file; its text is stored so replay rebuilds it exactly. A single
        robot's scenario, or a team of one made from one (``TeamScenario.solo``), is written
        in a single robot's format, byte for byte as before 0.3.0; a team in a team's.
    seed : int
    filters : list of str
        The filter specs of the run.
    params : dict
        ``{NAME: {KEY: VALUE}}`` parameter overrides (``--set``) of the run.

    Call :meth:`record_tick` once per tick *before* the caller's step of that tick, with the
    driven robot, its command, whether its own driver chose it and the user commands applied
    on that tick; then :meth:`close`.

    A shadow :class:`~beacon_sim.core.team.TeamSimulation` gives the checksums. The file is
    created exclusively (two sessions never write one file: the second gets ``-2``
    appended) and flushed at least every :data:`FLUSH_EVERY_S` of simulated or wall time (a
    killed program's file replays to within a second of the kill). With
    :data:`~beacon_sim.io.recording.KEY_VARIABLE` set, a running HMAC signs it (a signature
    line after every checkpoint and after the end line). :meth:`attach` hands the recorder
    the session's filters: the filters line (every filter's effective parameters) is written
    at once, and the digests of the filters' estimates after each checkpoint's tick and at
    the end (version 3).
    """

    def __init__(self, path, scenario: Scenario | TeamScenario, seed: int, filters: list[str],
                 params: dict | None = None, *, checkpoint_every: int | None = None):
        team = as_team(scenario)
        self.team = team
        self.solo = team.solo
        text = scenario_text(team)
        stored_map: dict[str, Any] = {}
        if self.solo:
            first = team.robots[0].scenario
            # A map file the scenario names goes into the header: the grid this
            # run uses, so a replay needs neither the file nor that it be unchanged.
            map_name = map_file_name(text, first.source)
            grid = first.world.grid if map_name is not None else None
            if grid is not None and map_name is not None:
                stored_map = {"map": map_header(grid, map_name)}
            rebuilt_one = rebuild_scenario(text, first.source, first.name, map_grid=grid)
            changed = replace(rebuilt_one, seed=first.seed, duration=first.duration) != first
            rebuilt = team_of_one(rebuilt_one)
        else:
            rebuilt = rebuild_team_scenario(text, team.source, team.name)
            changed = replace(rebuilt, seed=team.seed, duration=team.duration) != team
        if changed:
            warnings.warn(f"{team.source}: the scenario was changed after loading; the "
                          "recording stores the file as it is on disk", stacklevel=2)
        self.shadow = TeamSimulation(rebuilt, int(seed))
        self.readings = TeamReadingsHash()
        extra = stored_map if self.solo else {"kind": TEAM_KIND,
                                              "robots": [r.name for r in team.robots]}
        self._open(path, team, text, seed, filters, params, checkpoint_every, extra)

    @property
    def scenario(self) -> Scenario | TeamScenario:
        """The recorded scenario: a single robot's :class:`Scenario`, or the team."""
        return self.team.robots[0].scenario if self.solo else self.team

    def _open(self, path, scenario: Any, text: str, seed: int, filters: list[str],
              params: dict | None, checkpoint_every: int | None,
              extra: dict[str, Any] | None = None) -> None:
        """Create the file and write the header (``extra``: fields after the common ones)."""
        self._runner: Any = None
        self.path = Path(path)
        self.seed = int(seed)
        self.dt = scenario.dt
        self.checkpoint_every = checkpoint_every or max(1, round(1.0 / scenario.dt))
        self.ticks = 0
        self._expected_tick: int | None = None
        self._warned_gap = False
        self._file: TextIO | None
        self._file, self.path = open_exclusive(self.path)
        key = recording_key()
        self._signer = Signer(key) if key is not None else None
        self.digests = EstimateDigests()
        self._notes: dict[str, str] = {}
        self._frozen: dict[str, str] = {}  # reloaded live: the digest when it was reloaded
        self._track_ids: dict[str, Any] = {}
        self._digested = 0  # the last tick whose estimates are in the digests
        header = {
            "type": "header", "format": FORMAT_NAME, "version": FORMAT_VERSION,
            "program_version": __version__,
            "created": _dt.datetime.now().astimezone().isoformat(timespec="seconds"),
            "scenario_name": scenario.name, "scenario_source": scenario_label(str(scenario.source)),
            "scenario_toml": text, "scenario_sha256": text_checksum(text),
            "seed": self.seed, "dt": scenario.dt,
            "filters": list(filters), "params": {k: dict(v) for k, v in (params or {}).items()},
            "checkpoint_every": self.checkpoint_every, "signed": self._signer is not None,
            "slip_model": CURRENT_SLIP_MODEL,  # the shadow's; absent: "legacy" (before 0.3.0)
            # which float64 kernels made the estimates: a replay on other maths
            # compares them within a tolerance, not bit for bit
            "maths": maths_fingerprint(), "maths_description": maths_description(),
            **(extra or {}),
        }
        self._write(header)
        self._flush()
        self._last_flush_wall = time.monotonic()
        self._last_flush_tick = 0

    def _write(self, obj: dict[str, Any]) -> None:
        """One line (signed when a key is set)."""
        assert self._file is not None
        text = dumps(obj) + "\n"
        try:
            self._file.write(text)
        except OSError as exc:
            raise self._disk_error(exc) from None
        if self._signer is not None:
            self._signer.add(text)

    def _disk_error(self, exc: OSError) -> RecordingError:
        """A write that failed (a full disk, a removed drive): one line naming the file."""
        return RecordingError(f"{self.path}: cannot write the recording: "
                              f"{exc.strerror or type(exc).__name__} (the file keeps the ticks "
                              "written before; it replays up to its last complete tick)")

    def _flush(self) -> None:
        assert self._file is not None
        try:
            self._file.flush()
        except OSError as exc:
            raise self._disk_error(exc) from None

    def _sign(self) -> None:
        if self._signer is not None:
            self._write({"type": "signature", "hmac": self._signer.hexdigest()})

    def attach(self, runner: Any) -> None:
        """The session's filters (a :class:`~beacon_sim.hosting.team_runner.TeamRunner`, or
        anything with ``tracks``: see :func:`~beacon_sim.io.recording.recorded_tracks`),
        before the first tick: writes the filters line (each filter's effective parameters,
        from the built filter) and digests its estimates from then on."""
        if self._file is None or self.ticks:
            return
        self._runner = runner
        settings: dict[str, dict[str, Any]] = {}
        for name, track in recorded_tracks(runner).items():
            self._track_ids[name] = id(track)
            entry: dict[str, Any] = {"params": effective_params(track.filter)
                                     if track.filter is not None else None}
            if track.failed:
                entry["failed"] = str(track.failed)[:200]
            settings[name] = entry
        self._write({"type": "filters", "filters": settings})

    def _digest_tick(self, tick: int) -> None:
        """The attached filters' estimates of ``tick`` into their digests (noting a filter
        switched off or reloaded live); an estimates line after a checkpoint's tick."""
        if self._runner is None or tick <= self._digested:
            return
        self._digested = tick
        tracks = {}
        for name, track in recorded_tracks(self._runner).items():
            if name not in self._track_ids:
                continue
            if id(track) != self._track_ids[name] and name not in self._frozen:
                self._frozen[name] = self.digests.digest(name)
                self._notes[name] = f"reloaded live at tick {tick}: its estimates are not compared"
            if track.failed and name not in self._notes:
                self._notes[name] = f"switched off live at tick {tick}: {str(track.failed)[:160]}"
            if name not in self._frozen:
                tracks[name] = track
        self.digests.update(tick, tracks)
        if tick % self.checkpoint_every == 0:
            self._write({"type": "estimates", "k": tick, "digests": self._digest_map(),
                         "values": self._values_map(tick),
                         **({"notes": dict(self._notes)} if self._notes else {})})
            self._sign()

    def _digest_map(self) -> dict[str, str | None]:
        return {n: None if n in self._frozen else self.digests.digest(n) for n in self._track_ids}

    def _values_map(self, tick: int) -> dict[str, list[float] | None]:
        """Each filter's estimate of ``tick`` (nine numbers per robot: ``estimate_values``),
        None for one reloaded live or without an estimate of that tick."""
        return {n: None if n in self._frozen else self.digests.values(n, tick)
                for n in self._track_ids}

    @property
    def truth_checksum(self) -> str:
        """Checksum of the true trajectory recorded so far (equals the caller's
        ``sim.truth_checksum`` after the same ticks, a single robot's ``Simulation``'s on a
        team of one: a cheap consistency check)."""
        return self.shadow.truth_checksum

    @property
    def readings_checksum(self) -> str:
        """Checksum of the readings recorded so far (a single robot's ``Simulation``'s on a
        team of one, :class:`TeamReadingsHash` on a team)."""
        return self.shadow.readings_checksum if self.solo else self.readings.checksum

    def _check_tick(self, tick: int) -> None:
        """Refuse a closed recorder; warn once when ticks are not recorded one by one."""
        if self._file is None:
            raise RecordingError(f"{self.path}: recorder already closed")
        if self._expected_tick is not None and tick != self._expected_tick and not self._warned_gap:
            warnings.warn(f"{self.path}: tick {tick} recorded after {self._expected_tick - 1}; "
                          "ticks should be recorded one by one", stacklevel=3)
            self._warned_gap = True
        self._expected_tick = tick + 1

    def _write_tick(self, line: dict[str, Any], tick: int) -> None:
        """The tick line, a checkpoint every ``checkpoint_every`` ticks, a flush when due."""
        assert self._file is not None
        self.ticks += 1
        self._write(line)
        if tick % self.checkpoint_every == 0:
            self._write(self._state_line("checkpoint"))
            if self._runner is None:
                self._sign()
        now = time.monotonic()
        if (now - self._last_flush_wall >= FLUSH_EVERY_S
                or (tick - self._last_flush_tick) * self.dt >= FLUSH_EVERY_S):
            self._flush()
            self._last_flush_wall = now
            self._last_flush_tick = tick


    def close(self) -> None:
        """Write the end line (final truth checksum) and close the file. Idempotent."""
        if self._file is None:
            return
        self._digest_tick(self.shadow.tick)
        end = self._state_line("end")
        if self._runner is not None:
            end["estimates"] = self._digest_map()
            end["values"] = self._values_map(self.shadow.tick)
            if self._notes:
                end["notes"] = dict(self._notes)
        file = self._file
        try:
            self._write(end)
            self._sign()
            file.close()
        except OSError as exc:
            raise self._disk_error(exc) from None
        finally:
            self._file = None
            with contextlib.suppress(OSError):
                file.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


    def record_tick(self, tick: int, driven: Any = 0, control: Any = None, autopilot: bool = False,
                    commands: list[dict] | None = None) -> None:
        """Record one tick: robot ``driven`` (index in team order) gets ``control`` [m/s,
        rad/s], the others follow their drivers; ``autopilot``: its own driver chose the
        command; ``commands``: the user commands applied before the step (a single robot's
        :data:`~beacon_sim.io.recording.COMMAND_KINDS`, a team's
        :data:`~beacon_sim.io.recording.TEAM_COMMAND_KINDS`). ``tick`` should count up by one
        per call (a gap is warned about once).

        A team of one writes a single robot's tick line: its command as given (``control``
        None: its driver's, the same draws ``step(None)`` would make). A team lets the
        driven robot's driver choose again on ``autopilot`` (the shadow's driver state
        follows) and writes what it chose. The call ``record_tick(tick, control, commands)``
        of a single robot (before 0.3.0) is still taken.
        """
        if driven is None or isinstance(driven, Control):  # (tick, control, commands)
            driven, control, commands, autopilot = 0, driven, control, False
        if self.solo:
            self._record_solo(tick, control, commands)
        else:
            self._record_team(tick, int(driven), control, autopilot, commands)

    def _record_solo(self, tick: int, control: Control | None, commands: list[dict] | None) -> None:
        sim = self.shadow.sims[0]
        commands = [dict(c) for c in (commands or [])]
        for c in commands:
            validate_command(c)
        self._check_tick(tick)
        self._digest_tick(sim.tick)
        apply_commands(commands, sim, {}, sim.scenario)
        if control is None:  # the driver's command (the same draws step(None) would make)
            control = sim.driver.control(sim.time, sim.pose)
        step = self.shadow.step({0: control})
        # "u" is the command the truth executed, not step.control (v = 0 after a bump, what
        # the filters are told): replaying step.control would re-run a different tick.
        line: dict[str, Any] = {"type": "tick", "k": step.tick,
                                "u": [control.v, control.omega],
                                "h": sim.truth_checksum[:8], "r": sim.readings_checksum[:8]}
        if commands:
            line["c"] = commands
        self._write_tick(line, step.tick)

    def _record_team(self, tick: int, driven: int, control: Control | None, autopilot: bool,
                     commands: list[dict] | None) -> None:
        n = self.team.n_robots
        commands = [_plain(c) for c in (commands or [])]
        for c in commands:
            validate_command(c, n)
        if not 0 <= driven < n:
            raise ValueError(f"driven robot {driven}: expected an index from 0 to {n - 1}")
        if control is None:
            autopilot = True
        self._check_tick(tick)
        self._digest_tick(self.shadow.tick)
        team_commands_to_sim(commands, self.shadow)
        step = self.shadow.step({} if autopilot or control is None else {driven: control})
        self.readings.update(step)
        # the command as given (a bump sets step.control's v to 0; replay needs what ran)
        u = step.steps[driven].control if autopilot or control is None else control
        line: dict[str, Any] = {"type": "tick", "k": step.tick, "d": driven, "u": [u.v, u.omega]}
        if autopilot:
            line["a"] = True
        line["h"] = self.shadow.truth_checksum[:8]
        line["r"] = self.readings.checksum[:8]
        if commands:
            line["c"] = commands
        self._write_tick(line, step.tick)

    def _state_line(self, kind: str) -> dict[str, Any]:
        """A checkpoint or the end line: the tick, the true pose(s) and the checksums."""
        sim = self.shadow
        out: dict[str, Any] = {"type": kind}
        if kind == "end":
            out["ticks"] = sim.tick
        else:
            out["k"] = sim.tick
            out["time"] = sim.time
        if self.solo:
            out["pose"] = [float(v) for v in sim.sims[0].pose]
        else:
            out["poses"] = [[float(v) for v in p] for p in sim.poses]
        out["checksum"] = self.truth_checksum
        out["readings_checksum"] = self.readings_checksum
        return out


class TeamReadingsHash:
    """SHA-256 of every reading of a team run, tick by tick: each robot's beacon readings
    and robot readings (sensor, kind, ``z``, IDs seen, HDOP, bit for bit, as a single robot's
    ``Simulation.readings_checksum``), prefixed with the robot's index. What a team
    recording's ``r`` and ``readings_checksum`` hold."""

    def __init__(self) -> None:
        self._hash = hashlib.sha256()

    def update(self, step: TeamStep) -> None:
        h = self._hash
        for i in range(len(step.steps)):
            for m in step.measurements(i):
                h.update(f"{step.tick} {i} {m.sensor} {m.kind} {m.z.shape}".encode())
                h.update(np.ascontiguousarray(m.z, dtype="<f8").tobytes())
                h.update(np.ascontiguousarray(m.beacon_ids, dtype="<i8").tobytes())
                h.update(np.float64(m.hdop).tobytes())

    @property
    def checksum(self) -> str:
        """First 16 hex digits."""
        return self._hash.hexdigest()[:16]


def team_commands_to_sim(commands: list[dict], sim: TeamSimulation) -> None:
    """The truth's part of team user commands: a kidnap request on the robot it names (to
    its ``pose``, or a random pose from that robot's events stream). Resets and toggles
    touch the filters and the display only."""
    for cmd in commands:
        if cmd["kind"] == "kidnap":
            sim.sims[cmd["robot"]].request_kidnap(cmd.get("pose"))


def _plain(cmd: dict) -> dict:
    """A command with JSON-ready values (a kidnap pose as a list of floats)."""
    out = dict(cmd)
    if "pose" in out and out["pose"] is not None:
        out["pose"] = [float(v) for v in out["pose"]]
    elif "pose" in out:
        del out["pose"]
    return out
