"""Writing a recording while a run goes (the format is beacon_sim/io/recording.py).

The recorder re-simulates alongside the caller (a shadow :class:`Simulation` from the same
scenario and seed, given the same controls and commands), so the file carries its own
checksums whatever the caller passes. Lines are flushed at least every half second of
simulated or wall time: a killed program leaves a file that replays to within a second of
the kill.
"""

from __future__ import annotations

import datetime as _dt
import time
import warnings
from dataclasses import replace
from pathlib import Path
from typing import Any, TextIO

from beacon_sim.core.scenario import Scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.core.types import Control
from beacon_sim.io.recording import (
    FLUSH_EVERY_S,
    FORMAT_NAME,
    FORMAT_VERSION,
    RecordingError,
    dumps,
    rebuild_scenario,
    scenario_text,
    text_checksum,
    validate_command,
)
from beacon_sim.runs.user_commands import apply_commands
from beacon_sim.version import __version__


class Recorder:
    """Writes one run to ``path`` as it goes.

    Parameters
    ----------
    path : str or Path
        The ``.jsonl`` file to create (its folder is created too).
    scenario : Scenario
        Loaded from a TOML file; its text is stored so replay rebuilds it exactly.
    seed : int
    filters : list of str
        The filter specs of the run.
    params : dict
        ``{NAME: {KEY: VALUE}}`` parameter overrides (``--set``) of the run.

    Call :meth:`record_tick` once per tick *before* the caller's ``sim.step`` of that tick,
    with the control and the user commands applied on that tick; then :meth:`close`.
    """

    def __init__(self, path, scenario: Scenario, seed: int, filters: list[str],
                 params: dict | None = None, *, checkpoint_every: int | None = None):
        self.path = Path(path)
        self.scenario = scenario
        self.seed = int(seed)
        text = scenario_text(scenario)
        rebuilt = rebuild_scenario(text, scenario.source, scenario.name)
        if replace(rebuilt, seed=scenario.seed, duration=scenario.duration) != scenario:
            warnings.warn(f"{scenario.source}: the scenario was changed after loading; the "
                          "recording stores the file as it is on disk", stacklevel=2)
        self.checkpoint_every = checkpoint_every or max(1, round(1.0 / scenario.dt))
        self.shadow = Simulation(rebuilt, self.seed)
        self.ticks = 0
        self._expected_tick: int | None = None
        self._warned_gap = False
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file: TextIO | None = self.path.open("w", encoding="utf-8", newline="\n")
        header = {
            "type": "header", "format": FORMAT_NAME, "version": FORMAT_VERSION,
            "program_version": __version__,
            "created": _dt.datetime.now().astimezone().isoformat(timespec="seconds"),
            "scenario_name": scenario.name, "scenario_source": str(scenario.source),
            "scenario_toml": text, "scenario_sha256": text_checksum(text),
            "seed": self.seed, "dt": scenario.dt,
            "filters": list(filters), "params": {k: dict(v) for k, v in (params or {}).items()},
            "checkpoint_every": self.checkpoint_every,
        }
        self._file.write(dumps(header) + "\n")
        self._file.flush()
        self._last_flush_wall = time.monotonic()
        self._last_flush_tick = 0

    @property
    def truth_checksum(self) -> str:
        """Checksum of the true trajectory recorded so far (equals the caller's
        ``sim.truth_checksum`` after the same ticks: a cheap consistency check)."""
        return self.shadow.truth_checksum

    def record_tick(self, tick: int, control: Control | None, commands: list[dict] | None = None) -> None:
        """Record the control [m/s, rad/s] and the user commands of one tick.

        ``control`` None means "the scenario's driver decides"; the driver's command is
        recorded. ``tick`` should count up by one per call (a gap is warned about once).
        """
        if self._file is None:
            raise RecordingError(f"{self.path}: recorder already closed")
        commands = [dict(c) for c in (commands or [])]
        for c in commands:
            validate_command(c)
        if self._expected_tick is not None and tick != self._expected_tick and not self._warned_gap:
            warnings.warn(f"{self.path}: tick {tick} recorded after {self._expected_tick - 1}; "
                          "ticks should be recorded one by one", stacklevel=2)
            self._warned_gap = True
        self._expected_tick = tick + 1
        apply_commands(commands, self.shadow, {}, self.shadow.scenario)
        step = self.shadow.step(control)
        self.ticks += 1
        line: dict[str, Any] = {"type": "tick", "k": step.tick,
                                "u": [step.control.v, step.control.omega],
                                "h": self.shadow.truth_checksum[:8],
                                "r": self.shadow.readings_checksum[:8]}
        if commands:
            line["c"] = commands
        self._file.write(dumps(line) + "\n")
        if step.tick % self.checkpoint_every == 0:
            self._file.write(dumps(self._state_line("checkpoint")) + "\n")
        now = time.monotonic()
        if (now - self._last_flush_wall >= FLUSH_EVERY_S
                or (step.tick - self._last_flush_tick) * self.scenario.dt >= FLUSH_EVERY_S):
            self._file.flush()
            self._last_flush_wall = now
            self._last_flush_tick = step.tick

    def _state_line(self, kind: str) -> dict[str, Any]:
        sim = self.shadow
        out: dict[str, Any] = {"type": kind}
        if kind == "end":
            out["ticks"] = sim.tick
        else:
            out["k"] = sim.tick
            out["time"] = sim.time
        out["pose"] = [float(v) for v in sim.pose]
        out["checksum"] = sim.truth_checksum
        out["readings_checksum"] = sim.readings_checksum
        return out

    def close(self) -> None:
        """Write the end line (final truth checksum) and close the file. Idempotent."""
        if self._file is None:
            return
        self._file.write(dumps(self._state_line("end")) + "\n")
        self._file.close()
        self._file = None

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
