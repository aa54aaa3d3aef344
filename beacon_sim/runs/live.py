"""A live session, without pygame: the simulation, the filters side by side, the keyboard's
command, user commands, trails and the figures the panel shows (a :class:`~beacon_sim.runs.scene.Scene`).

Every tick goes the same way (``Session.tick``): take the command (keyboard or autopilot),
take the user commands queued since the last tick, hand both to the recorder, apply the
commands through ``user_commands.apply_commands``, step the simulation, feed the filters.
So a replay of (command, user commands) per tick reproduces the session bit for bit.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from beacon_sim.core.drivers import KeyboardSpec
from beacon_sim.core.keyboard_drive import KeyboardDrive, KeyboardLimits
from beacon_sim.core.scenario import Scenario
from beacon_sim.core.schedule import tick_schedule
from beacon_sim.core.simulation import Simulation
from beacon_sim.core.types import Control, EventRecord, Measurement, Step
from beacon_sim.filters.base import Belief, Filter, GaussianBelief
from beacon_sim.filters.loading import WINDOW_BUILD_LIMIT_S, build_filters, reset_filter
from beacon_sim.filters.runner import (
    WINDOW_STEP_LIMIT_S,
    FilterRunner,
    FilterTrack,
    bounded_track,
    guarded_call,
    status_line,
    validate_belief,
    validate_estimate,
)
from beacon_sim.io.recording import default_recording_path, validate_command
from beacon_sim.runs.recorder import Recorder
from beacon_sim.runs.scene import FilterStatus, Trail
from beacon_sim.runs.user_commands import apply_commands, apply_to_filters

#: A reloaded filter catches up over the session's history when that takes at most this
#: long [s] (estimated from its first steps); otherwise it restarts from the initial belief.
CATCH_UP_BUDGET_S = 1.5
#: The session keeps every Step for a catch-up up to this much simulated time [s] (about
#: 0.7 kB a tick: 20 minutes at 20 Hz is 17 MB); later reloads start from the initial belief.
HISTORY_S = 1200.0
#: Estimates a window's session keeps per filter (the screen needs the latest; a rebuilt
#: trail at most this many points, the trail's own cap): memory does not grow with time.
KEEP_ESTIMATES = 6000


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
        built, broken = build_filters(self.specs, sc, self.seed, self.params,
                                      limit_s=WINDOW_BUILD_LIMIT_S)
        self.names = list(built)
        self.runner = FilterRunner(built, step_limit_s=WINDOW_STEP_LIMIT_S, keep=KEEP_ESTIMATES)
        for name, (why, tb) in broken.items():
            self.runner.fail(name, why, tb)
        self.runner.priors = {}
        self._keep_priors()
        if self.recorder is not None and hasattr(self.recorder, "attach"):
            self.recorder.attach(self.runner)  # the recording stores the filters' settings
        # Called with every Step after the filters are fed (the window's live bound); kept
        # over a replay's rebuild (a seek back re-runs __post_init__).
        self.on_step: list[Callable[[Step], None]] = getattr(self, "on_step", [])
        self.sim = Simulation(sc, self.seed)
        self.keyboard = KeyboardDrive(sc.keyboard)
        self.has_autopilot = not isinstance(sc.driver, KeyboardSpec)
        self.autopilot = False
        self.pending: list[dict] = []
        self.visible = {n: True for n in self.names}
        # the command of every tick, in order, over the kept history
        self.controls: deque[Control] = deque(maxlen=round(HISTORY_S / sc.dt) + 1)
        self.steps: list[Step] = []  # every tick's Step, for a reloaded filter to catch up
        self.commands: dict[int, list[dict]] = {}  # tick -> user commands applied on it
        self.last_step: Step | None = None
        self.last_readings: dict[str, tuple[int, Measurement]] = {}
        self.recent_events: list[EventRecord] = []
        self.truth_trail = Trail()
        self.truth_trail.add(sc.initial_pose)
        self.trails = {n: Trail() for n in self.names}
        self.status = {n: FilterStatus(n) for n in self.names}
        self._every = tick_schedule(sc).every
        for n in self.names:
            est = self.estimate(n)
            if est is not None:
                self.trails[n].add(est[0])

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

    def _last_control(self) -> tuple[float, float]:
        """The last command, rounded to the keyboard's steps (taking over from the autopilot:
        its omega +0.036 would keep the robot curving after the keys are let go) and clamped
        to the keyboard's limits."""
        return taken_over(self.controls[-1] if self.controls else Control(), self.keyboard.limits)

    def next_control(self) -> Control:
        if self.autopilot:
            return self.sim.driver.control(self.sim.time, self.sim.pose)
        return self.keyboard.control

    @property
    def drive_mode(self) -> str:
        """Who drives, for the panel."""
        return "AUTOPILOT (M)" if self.autopilot else "keyboard WASD, X stop"

    # --- what a window reads (the Scene protocol) -------------------------------------------
    @property
    def tick_count(self) -> int:
        return self.sim.tick

    @property
    def time(self) -> float:
        return self.sim.time

    @property
    def true_pose(self) -> np.ndarray:
        return self.sim.pose

    def belief(self, name: str) -> Belief | None:
        """The filter's belief to draw, through the runner's guard (time limit, types,
        shapes, finite values): None, and the filter switched off with the reason, when
        ``belief()`` raises, hangs or returns something that cannot be drawn."""
        tr = self.runner.tracks[name]
        if tr.failed or tr.filter is None:
            return None
        # A filter changes only in a tick (commands included) or when it is replaced: the
        # belief read and checked once per tick serves every frame until the next (a 10k-
        # particle or 86,400-cell belief is copied and checked, about 0.2 ms a frame).
        cache = self.__dict__.setdefault("_beliefs", {})
        hit = cache.get(name)
        if hit is not None and hit[0] == self.sim.tick and hit[1] is tr.filter:
            return hit[2]
        bel = self._guarded_read(name, tr.filter.belief, validate_belief, "belief(): ")
        if bel is not None:
            cache[name] = (self.sim.tick, tr.filter, bel)
        return bel

    def estimate(self, name: str) -> tuple[np.ndarray, np.ndarray] | None:
        """The latest estimate; before the first tick, the filter's initial belief (through
        the guard: None, and the filter switched off, when it is unusable)."""
        tr = self.runner.tracks[name]
        if tr.means:
            return tr.means[-1], tr.covs[-1]
        if tr.failed or tr.filter is None:
            return None
        return self._guarded_read(name, tr.filter.estimate, validate_estimate)

    def _guarded_read(self, name: str, call: Callable[[], object],
                      validate: Callable[[object], Any], raised_prefix: str = "") -> Any:
        """``validate(call())`` under the window's time limit; None, and the filter switched
        off with the reason, when the call raises, hangs or returns something unusable."""
        value, why, tb = guarded_call(call, WINDOW_STEP_LIMIT_S)
        if why is None:
            checked = validate(value)
            if not isinstance(checked, str):
                return checked
            why = checked
        else:
            why = raised_prefix + why
        self._switch_off(name, why, tb)
        return None

    def _switch_off(self, name: str, why: str, tb: str = "") -> None:
        self.runner.fail(name, why, tb, self.sim.time)
        self.status[name].failed = self.runner.tracks[name].failed
        self.status[name].warning = status_line(self.runner.tracks[name])

    @property
    def filters(self) -> dict[str, object]:
        return {n: t.filter for n, t in self.runner.tracks.items() if t.filter is not None}

    def replace_filter(self, name: str, flt: Filter, budget_s: float = CATCH_UP_BUDGET_S) -> str:
        """Swap in a new filter object under ``name`` (hot reload), same colour.

        The new filter is run over every tick of the session so far (the same Steps and the
        same resets the others had), so it appears where it would be had it run from the
        start. When that would take longer than ``budget_s`` [s] (judged on its first
        steps) it starts from the initial belief instead. Returns what happened, in words.
        """
        if len(self.steps) < self.sim.tick:  # the history was not kept this far
            reset_filter(flt, self.scenario)
            self._install(name, bounded_track(name, flt, KEEP_ESTIMATES))
            return (f"{name} reloaded from the initial belief (the session keeps "
                    f"{HISTORY_S / 60:.0f} minutes of history to catch up over)")
        catch_up = FilterRunner({name: flt}, step_limit_s=WINDOW_STEP_LIMIT_S, keep=KEEP_ESTIMATES)
        t0 = time.perf_counter()
        for i, step in enumerate(self.steps):
            cmds = self.commands.get(step.tick)
            if cmds and not catch_up.tracks[name].failed:
                for _, (why, tb) in apply_to_filters(cmds, {name: flt}, self.scenario,
                                                     WINDOW_STEP_LIMIT_S).items():
                    catch_up.fail(name, why, tb, step.time - step.dt)
            catch_up.feed(step)
            elapsed = time.perf_counter() - t0
            if catch_up.tracks[name].failed:
                break
            if i in (19, 199) and elapsed * len(self.steps) / (i + 1) > budget_s:
                projected = elapsed * len(self.steps) / (i + 1)
                reset_filter(flt, self.scenario)
                self._install(name, bounded_track(name, flt, KEEP_ESTIMATES))
                return (f"{name} reloaded from the initial belief: catching up over "
                        f"{len(self.steps)} ticks would take about {projected:.0f} s")
        self._install(name, catch_up.tracks[name])
        if not self.steps:
            return f"{name} reloaded"
        return (f"{name} reloaded and run over the {len(self.steps)} ticks so far "
                f"({time.perf_counter() - t0:.2f} s)")

    def _install(self, name: str, track: FilterTrack) -> None:
        """Put ``track`` in the runner under ``name``; rebuild its trail and status from it."""
        self.runner.tracks[name] = track
        trail = self.trails[name] = Trail()
        for mean in track.means:
            trail.add(mean)
        st = self.status[name] = FilterStatus(name)
        st.failed, st.warning = track.failed, status_line(track)
        if track.means and self.last_step is not None and track.ticks[-1] == self.last_step.tick:
            st.measure(track.means[-1], track.covs[-1], self.last_step.true_pose)
        self.runner.priors.pop(name, None)
        self._keep_priors()

    # --- the step view: predict, then update, of the last tick ------------------------------
    def _keep_priors(self) -> None:
        """Ask the runner to keep the belief after predict of every Gaussian filter (one whose
        ``belief()`` is a GaussianBelief); the others' beliefs have no single ellipse."""
        keep = set()
        for name, tr in self.runner.tracks.items():
            if tr.filter is None or tr.failed:
                continue
            # a student's belief() may raise (or exit, or hang) before the first tick
            bel, why, _ = guarded_call(tr.filter.belief, WINDOW_STEP_LIMIT_S)
            if why is None and isinstance(bel, GaussianBelief):
                keep.add(name)
        self.runner.keep_prior = frozenset(keep)

    def predict_update(self, name: str) -> tuple[tuple[np.ndarray, np.ndarray],
                                                  tuple[np.ndarray, np.ndarray]] | None:
        """The last tick of a Gaussian filter: ``((mean, cov) after predict, (mean, cov) after
        update)`` [m, m, rad], or None (not Gaussian, switched off, no tick yet)."""
        tr = self.runner.tracks.get(name)
        prior = self.runner.priors.get(name)
        if (tr is None or prior is None or tr.failed or self.last_step is None or not tr.ticks
                or tr.ticks[-1] != self.last_step.tick):
            return None
        return prior, (tr.means[-1], tr.covs[-1])

    def used_ids(self) -> set[int]:
        """The beacons in the last tick's readings: the ones its update used."""
        if self.last_step is None:
            return set()
        return {int(i) for m in self.last_step.measurements for i in m.beacon_ids}

    # --- one tick -------------------------------------------------------------------------
    def tick(self) -> Step:
        """Run one simulation tick with the current command and the queued user commands."""
        control = self.next_control()
        cmds, self.pending = self.pending, []
        tick = self.sim.tick + 1
        if self.recorder is not None:
            self.recorder.record_tick(tick, control, cmds)
        working = {n: t.filter for n, t in self.runner.tracks.items() if t.filter and not t.failed}
        for name, (why, tb) in apply_commands(cmds, self.sim, working, self.scenario,
                                              WINDOW_STEP_LIMIT_S).items():
            self._switch_off(name, why, tb)
        if any(c["kind"] in ("reset", "global_reset") for c in cmds):
            for tr in self.trails.values():
                tr.brk()
        step = self.sim.step(control)
        self.runner.feed(step)
        if step.time <= HISTORY_S:
            self.steps.append(step)
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
        if not self.autopilot and any(e.kind == "bump" for e in step.events):
            self.keyboard.v = 0.0  # the bumper stopped the robot: the command says so too
        self.recent_events.extend(step.events)
        del self.recent_events[:-20]
        truth = step.true_pose
        for name, tr in self.runner.tracks.items():
            st = self.status[name]
            st.failed = tr.failed
            st.warning = status_line(tr)
            if tr.failed or not tr.ticks or tr.ticks[-1] != step.tick:
                continue
            self.trails[name].add(tr.means[-1])
            st.measure(tr.means[-1], tr.covs[-1], truth)
        for listener in self.on_step:
            listener(step)

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


def taken_over(c: Control, limits: KeyboardLimits) -> tuple[float, float]:
    """``(v, omega)`` the keyboard starts from when it takes over command ``c``: each rounded
    to the nearest multiple of its step (``v_step``, ``omega_step``), clamped to the limits."""
    v = round(c.v / limits.v_step) * limits.v_step
    w = round(c.omega / limits.omega_step) * limits.omega_step
    v = round(min(max(v, limits.v_min), limits.v_max), 9)
    w = round(min(max(w, -limits.omega_max), limits.omega_max), 9)
    return v + 0.0, w + 0.0


def make_recorder(scenario: Scenario, seed: int, specs: list[str],
                  params: dict[str, dict[str, Any]]) -> tuple[Recorder, Path]:
    """A recorder writing to ``recordings/<scenario>_<time>.jsonl``, and that path."""
    recorder = Recorder(Path(default_recording_path(scenario.name)), scenario, seed, list(specs),
                        params)
    return recorder, recorder.path  # (another name when that one was just taken)
