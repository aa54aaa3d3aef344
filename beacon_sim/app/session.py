"""What a window session runs, without pygame: the simulation, the filters side by side, the
keyboard's command, user commands, trails and the figures the HUD shows.

Every tick goes the same way (``Session.tick``): take the command (keyboard or autopilot),
take the user commands queued since the last tick, hand both to the recorder, apply the
commands through ``user_commands.apply_commands``, step the simulation, feed the filters.
So a replay of (command, user commands) per tick reproduces the session bit for bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from beacon_sim.core.angles import diff
from beacon_sim.core.drivers import KeyboardSpec
from beacon_sim.core.keyboard_drive import KeyboardDrive
from beacon_sim.core.scenario import Scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.core.types import Control, EventRecord, Measurement, Step
from beacon_sim.filters.loading import build_filter, filter_display_name, filter_names
from beacon_sim.filters.runner import FilterRunner, FilterTrack
from beacon_sim.user_commands import apply_commands, validate_command

#: Single-sample NEES band: the 2.5 % and 97.5 % quantiles of chi-square with 3 degrees of
#: freedom (tables); outside it the HUD highlights the value.
NEES_BAND = (0.2158, 9.3484)


class Trail:
    """A polyline in metres with breaks (kidnaps, resets), thinned to ``min_step`` metres
    and capped at ``max_points`` (the oldest half is dropped when full)."""

    def __init__(self, min_step: float = 0.02, max_points: int = 6000):
        self.min_step = min_step
        self.max_points = max_points
        self.points = np.full((max_points, 2), np.nan)
        self.n = 0
        self._last = np.array([np.nan, np.nan])

    def add(self, xy) -> None:
        xy = np.asarray(xy, dtype=float)[:2]
        if self.n and np.isfinite(self._last[0]) and math.hypot(*(xy - self._last)) < self.min_step:
            return
        self._append(xy)
        self._last = xy

    def brk(self) -> None:
        """Start a new piece: the next point is not joined to the previous one."""
        if self.n and np.isfinite(self.points[self.n - 1, 0]):
            self._append(np.array([np.nan, np.nan]))
        self._last = np.array([np.nan, np.nan])

    def _append(self, xy) -> None:
        if self.n == self.max_points:
            half = self.max_points // 2
            self.points[:half] = self.points[half:]
            self.points[half:] = np.nan
            self.n = half
        self.points[self.n] = xy
        self.n += 1

    def pieces(self) -> list[np.ndarray]:
        """The unbroken pieces, each shape (k, 2) [m] with k >= 2."""
        pts = self.points[: self.n]
        if not len(pts):
            return []
        cut = np.flatnonzero(np.isnan(pts[:, 0]))
        out = []
        for seg in np.split(pts, cut):
            seg = seg[np.isfinite(seg[:, 0])]
            if len(seg) >= 2:
                out.append(seg)
        return out


@dataclass
class FilterStatus:
    """What the HUD shows for one filter after the latest tick."""

    name: str
    pos_err: float = math.nan  # [m]
    heading_err: float = math.nan  # [rad]
    nees: float = math.nan
    failed: str | None = None

    def measure(self, mean, cov, truth) -> None:
        """The errors [m, rad] and NEES of the estimate ``(mean, cov)`` against ``truth``."""
        e = np.array([mean[0] - truth[0], mean[1] - truth[1], diff(mean[2], truth[2])])
        self.pos_err = math.hypot(e[0], e[1])
        self.heading_err = float(e[2])
        try:
            self.nees = float(e @ np.linalg.solve(cov, e))
        except np.linalg.LinAlgError:
            self.nees = math.inf

    @property
    def nees_out_of_band(self) -> bool:
        return math.isfinite(self.nees) and not NEES_BAND[0] <= self.nees <= NEES_BAND[1]


@dataclass
class Session:
    """A scenario, a seed and named filters, advanced one tick at a time.

    Parameters
    ----------
    scenario : Scenario
    specs : list of str
        Filter specs (built-in names, ``pkg.mod:Class``, ``file.py:Class``).
    seed : int, optional
        Defaults to the scenario's.
    params : dict, optional
        ``{filter_name: {param: value}}`` overrides (from ``--set``).
    recorder : object, optional
        Anything with ``record_tick(tick, control, commands)`` and ``close()``.
    """

    scenario: Scenario
    specs: list[str]
    seed: int | None = None
    params: dict[str, dict[str, Any]] = field(default_factory=dict)
    recorder: Any = None

    def __post_init__(self) -> None:
        sc = self.scenario
        self.seed = sc.seed if self.seed is None else int(self.seed)
        built: dict[str, object] = {}
        for name, spec in zip(filter_names(self.specs), self.specs, strict=True):
            built[name] = build_filter(spec, sc, self.seed, name=name,
                                       params=self.params.get(filter_display_name(spec)))
        self.names = list(built)
        self.runner = FilterRunner(built)
        self.sim = Simulation(sc, self.seed)
        self.keyboard = KeyboardDrive(sc.keyboard)
        self.has_autopilot = not isinstance(sc.driver, KeyboardSpec)
        self.autopilot = False
        self.pending: list[dict] = []
        self.visible = {n: True for n in self.names}
        self.controls: list[Control] = []  # the command of every tick, in order
        self.commands: dict[int, list[dict]] = {}  # tick -> user commands applied on it
        self.last_step: Step | None = None
        self.last_readings: dict[str, tuple[int, Measurement]] = {}
        self.recent_events: list[EventRecord] = []
        self.truth_trail = Trail()
        self.truth_trail.add(sc.initial_pose)
        self.trails = {n: Trail() for n in self.names}
        self.status = {n: FilterStatus(n) for n in self.names}
        self._every = {s.name: max(1, round(s.period / sc.dt)) for s in sc.sensors}
        for n, tr in self.runner.tracks.items():
            self.trails[n].add(tr.filter.estimate()[0])

    # --- commands -------------------------------------------------------------------------
    def command(self, cmd: dict) -> None:
        """Queue a user command for the next tick (``toggle`` also shows/hides at once)."""
        validate_command(cmd)
        if cmd["kind"] == "toggle" and cmd.get("filter") in self.visible:
            self.visible[cmd["filter"]] = not self.visible[cmd["filter"]]
        self.pending.append(dict(cmd))

    def drive(self, key: str) -> None:
        """W/S/A/D/X on the keyboard's command; driving by hand switches the autopilot off."""
        if self.autopilot:
            self.autopilot = False
            self.keyboard.v, self.keyboard.omega = self._last_control()
        self.keyboard.press(key)

    def toggle_autopilot(self) -> None:
        self.autopilot = self.has_autopilot and not self.autopilot
        if not self.autopilot:
            self.keyboard.v, self.keyboard.omega = self._last_control()
            self.keyboard._clamp()

    def _last_control(self) -> tuple[float, float]:
        c = self.controls[-1] if self.controls else Control()
        return c.v, c.omega

    def next_control(self) -> Control:
        if self.autopilot:
            return self.sim.driver.control(self.sim.time, self.sim.pose)
        return self.keyboard.control

    @property
    def drive_mode(self) -> str:
        """Who drives, for the panel."""
        return "AUTOPILOT (M)" if self.autopilot else "keyboard WASD, X stop"

    @property
    def filters(self) -> dict[str, object]:
        return {n: t.filter for n, t in self.runner.tracks.items()}

    def replace_filter(self, name: str, flt: object) -> None:
        """Swap in a new filter object under ``name`` (hot reload): a fresh track, same colour."""
        self.runner.tracks[name] = FilterTrack(name, flt)
        self.trails[name].brk()
        self.status[name] = FilterStatus(name)

    # --- one tick -------------------------------------------------------------------------
    def tick(self) -> Step:
        """Run one simulation tick with the current command and the queued user commands."""
        control = self.next_control()
        cmds, self.pending = self.pending, []
        tick = self.sim.tick + 1
        if self.recorder is not None:
            self.recorder.record_tick(tick, control, cmds)
        apply_commands(cmds, self.sim, self.filters, self.scenario)
        if any(c["kind"] in ("reset", "global_reset") for c in cmds):
            for tr in self.trails.values():
                tr.brk()
        step = self.sim.step(control)
        self.runner.feed(step)
        self.controls.append(control)
        if cmds:
            self.commands[tick] = cmds
        self._after(step)
        return step

    def _after(self, step: Step) -> None:
        self.last_step = step
        for m in step.measurements:
            self.last_readings[m.sensor] = (step.tick, m)
        for name in list(self.last_readings):
            if step.tick - self.last_readings[name][0] >= self._every.get(name, 1):
                del self.last_readings[name]
        if step.kidnapped:
            self.truth_trail.brk()
        self.truth_trail.add(step.true_pose)
        self.recent_events.extend(step.events)
        del self.recent_events[:-20]
        truth = step.true_pose
        for name, tr in self.runner.tracks.items():
            st = self.status[name]
            st.failed = tr.failed
            if tr.failed or not tr.ticks or tr.ticks[-1] != step.tick:
                continue
            self.trails[name].add(tr.means[-1])
            st.measure(tr.means[-1], tr.covs[-1], truth)

    def readings(self) -> list[Measurement]:
        """The latest reading of each sensor still within its period."""
        return [m for _, m in self.last_readings.values()]

    def seen_ids(self) -> set[int]:
        out: set[int] = set()
        for m in self.readings():
            out.update(int(i) for i in m.beacon_ids)
        return out

    def close(self) -> None:
        if self.recorder is not None:
            self.recorder.close()
            self.recorder = None


def make_recorder(scenario: Scenario, seed: int, specs: list[str],
                  params: dict[str, dict[str, Any]]) -> tuple[Any, Path | None]:
    """A recorder from ``beacon_sim.recording`` when that module exists, else ``(None, None)``."""
    try:
        from beacon_sim.recording import Recorder, default_recording_path
    except ImportError:
        return None, None
    path = Path(default_recording_path(scenario.name))
    return Recorder(path, scenario, seed, list(specs), params), path
