"""A live session, without pygame: the simulation of one robot or a team, the filters side by
side, the keyboard's command for the driven robot, user commands, trails and the figures the
panel shows (a :class:`~beacon_sim.runs.scene.Scene`).

A single robot is a team of one: :class:`Session` runs any scenario as a team
(``core.scenario.as_team``), its :class:`~beacon_sim.core.team.TeamSimulation` and a
:class:`~beacon_sim.hosting.team_runner.TeamRunner`. On a team of one it builds and feeds
exactly what a single-robot session always did (the same truth, the same estimates, the same
recording); on a team, Tab changes the driven robot and the others follow their drivers.

Every tick goes the same way (``Session.tick``): take the driven robot's command (keyboard
or autopilot), take the user commands queued since the last tick, hand both to the recorder,
apply the commands through ``user_commands``, step every robot, feed the filters. So a
replay of (driven robot, command, user commands) per tick reproduces the session bit for
bit, whatever the frame rate.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from beacon_sim.core.keyboard_drive import KeyboardDrive
from beacon_sim.core.scenario import Scenario, TeamScenario, as_team
from beacon_sim.core.schedule import tick_schedule
from beacon_sim.core.team import TeamSimulation, TeamStep
from beacon_sim.core.types import Control, EventRecord, Measurement, Step
from beacon_sim.filters.base import Belief, GaussianBelief
from beacon_sim.hosting.loading import WINDOW_BUILD_LIMIT_S
from beacon_sim.hosting.runner import (
    WINDOW_STEP_LIMIT_S,
    FilterRunner,
    call_guarded,
    status_line,
    validate_belief,
    validate_estimate,
)
from beacon_sim.hosting.team_runner import JointRunner, TeamRunner, team_filter_of, validate_team_estimates
from beacon_sim.io.recording import TEAM_COMMAND_KINDS, default_recording_path, validate_command
from beacon_sim.runs.filter_snapshot import FilterTick, filter_tick, read_drawing
from beacon_sim.runs.filter_swapping import HISTORY_S, KEEP_ESTIMATES, FilterSwapping
from beacon_sim.runs.filter_worker import FilterWorker, WorkerTicks
from beacon_sim.runs.recorder import Recorder
from beacon_sim.runs.scene import FilterStatus, Trail
from beacon_sim.runs.session_driving import SessionDriving
from beacon_sim.runs.user_commands import apply_to_run, commands_to_sim

#: Points of each estimate's trail on a team (one per filter and robot): about 20 s of a
#: robot at 0.3 m/s, so that a dozen estimate trails do not bury the truth's (which keeps
#: the usual 6000). A single robot's estimate trails keep the usual cap.
TEAM_TRAIL_POINTS = 300


class Session(WorkerTicks, FilterSwapping, SessionDriving):
    """A scenario (one robot or a team), a seed and named filters, advanced one tick at a time.

    Parameters
    ----------
    scenario : Scenario or TeamScenario
        A single-robot scenario runs as a team of one.
    specs : list of str
        Filter specs: on a single robot, built-in names, ``pkg.mod:Class``, ``file.py:Class``;
        on a team, team filter names or ``independent:F`` (see ``hosting/team_specs.py``).
    seed : int, optional
        Defaults to the scenario's.
    params : dict, optional
        ``{filter_name: {param: value}}`` overrides (from ``--set``).
    recorder : object, optional
        Anything with ``record_tick(tick, driven, control, autopilot, commands)`` and
        ``close()`` (``runs/recorder``: the session written as it goes).
    """

    def __init__(self, scenario: Scenario | TeamScenario, specs: list[str], seed: int | None = None,
                 params: dict[str, dict[str, Any]] | None = None, recorder: Any = None):
        self.team = as_team(scenario)
        self.specs = list(specs)
        self.seed: int = self.team.seed if seed is None else int(seed)
        self.params = dict(params or {})
        self.recorder = recorder
        # Called with the single robot's Step after the filters are fed (the window's live
        # bound, the live MCAP stream); kept over a restart.
        self.on_step: list[Callable[[Step], None]] = []
        #: The thread the filters run on (:meth:`start_worker`), None: in each tick (the default).
        self.worker: FilterWorker | None = None
        self.filter_cpu_s = 0.0  # CPU time of the filters' part of every tick so far [s]
        self._fail_time = 0.0  # on the worker: the simulated time of the tick it feeds [s]
        self.restart()
        if self.recorder is not None and hasattr(self.recorder, "attach"):
            # the recording stores the filters' settings and digests their estimates
            self.recorder.attach(self.filters_run)

    def restart(self) -> None:
        """A fresh start: a new simulation from tick 0, the filters built and reset again,
        empty trails (what a replay's seek back uses)."""
        threaded = self.worker is not None
        if threaded:
            self.stop_worker()
        team = self.team
        self.filters_run = TeamRunner(team, self.specs, self.seed, self.params,
                                      step_limit_s=WINDOW_STEP_LIMIT_S, keep=KEEP_ESTIMATES,
                                      cpu_limits=True, build_limit_s=WINDOW_BUILD_LIMIT_S)
        self.names = list(self.filters_run.names)
        for runner in self.filters_run.members:
            runner.priors = {}
        self._keep_priors()
        self.sim = TeamSimulation(team, self.seed)
        self.n_robots = team.n_robots
        self.robot_names = [r.name for r in team.robots]
        self.driven = 0
        self.keyboard = KeyboardDrive(team.keyboard)
        self.autopilot = False
        self.pending: list[dict] = []
        self._shown: list[dict] = []  # a team's show / hide since the last tick
        self.visible = {n: True for n in self.names}
        self.last_controls: list[Control] = [Control() for _ in team.robots]
        # the driven robot's command of every tick, in order, over the kept history
        self.controls: deque[Control] = deque(maxlen=round(HISTORY_S / team.dt) + 1)
        self.steps: list[TeamStep] = []  # every tick, for a reloaded filter to catch up
        self.commands: dict[int, list[dict]] = {}  # tick -> user commands applied on it
        self.last_step: TeamStep | None = None
        # robot index -> sensor name -> (tick, reading): the latest reading within its period
        self._readings: list[dict[str, tuple[int, Measurement]]] = [{} for _ in team.robots]
        self._every = [tick_schedule(r.scenario, r.robot_sensors).every for r in team.robots]
        self.recent_events: list[EventRecord] = []
        self.truth_trails = [Trail() for _ in team.robots]
        for trail, r in zip(self.truth_trails, team.robots, strict=True):
            trail.add(r.scenario.initial_pose)
        points = {} if team.solo else {"max_points": TEAM_TRAIL_POINTS}
        self.trails = {n: [Trail(**points) for _ in team.robots] for n in self.names}
        self.robot_status = {n: [FilterStatus(n if team.solo else f"{n}/{r}")
                                 for r in self.robot_names] for n in self.names}
        self.status = {n: self.robot_status[n][0] if team.solo else FilterStatus(n)
                       for n in self.names}
        self._beliefs: dict[str, tuple[int, Any, Belief]] = {}
        # With a worker (:meth:`start_worker`): the filters as of the tick shown
        # (``runs/filter_snapshot``), the ticks the worker finished and not shown yet, and
        # the tick shown (it may be a frame behind the simulation's).
        self._state: FilterTick | None = None
        self._waiting: list[tuple[TeamStep, list[dict], FilterTick]] = []
        self._shown_at: tuple[int, float, np.ndarray] = (0, self.sim.time, self.sim.poses)
        for n in self.names:
            self._sync_status(n)
            est = self.estimates(n)
            if est is not None:
                for trail, mean in zip(self.trails[n], est[0], strict=True):
                    trail.add(mean)
        if threaded:
            self.start_worker()

    # --- what the session is ---------------------------------------------------------------
    @property
    def scenario(self) -> Scenario:
        """The driven robot's scenario (on a team of one: the scenario itself)."""
        return self.team.robots[self.driven].scenario

    @property
    def runner(self) -> FilterRunner:
        """Robot 1's single-robot filters (on a team of one: every filter of the session)."""
        return self.filters_run.members[0]

    @property
    def joint(self) -> JointRunner:
        """The team filters (none on a team of one)."""
        return self.filters_run.joint

    @property
    def driven_name(self) -> str:
        return self.robot_names[self.driven]

    def robot_index(self, robot_id: int) -> int | None:
        for k, r in enumerate(self.team.robots):
            if r.id == robot_id:
                return k
        return None

    # --- commands -------------------------------------------------------------------------
    def command(self, cmd: dict) -> None:
        """Queue a user command for the next tick (``toggle`` also shows/hides at once). On a
        team a ``kidnap`` acts on the robot driven when it is given, a ``reset`` on every
        filter."""
        validate_command(cmd)
        kind = cmd["kind"]
        if not self.team.solo and kind not in TEAM_COMMAND_KINDS:
            raise ValueError(f"a team session has no command {kind!r}")
        if kind == "toggle" and cmd.get("filter") in self.visible:
            self.visible[cmd["filter"]] = not self.visible[cmd["filter"]]
        if self.team.solo:
            self.pending.append(dict(cmd))
        elif kind == "toggle":
            if cmd.get("filter") in self.visible:
                self._shown.append({"kind": "toggle", "filter": cmd["filter"]})
        else:
            self.pending.append({**cmd, "robot": self.driven})

    # --- what a window reads (the Scene protocol) -------------------------------------------
    # With a worker the scene is the tick shown (the filters' latest finished tick, a frame
    # behind the simulation at most), truth and estimates alike.
    @property
    def tick_count(self) -> int:
        return self.sim.tick if self.worker is None else self._shown_at[0]

    @property
    def time(self) -> float:
        return self.sim.time if self.worker is None else self._shown_at[1]

    @property
    def poses(self) -> np.ndarray:
        """Every robot's true pose now, shape (N, 3) [m, m, rad]."""
        return self.sim.poses if self.worker is None else self._shown_at[2]

    @property
    def true_pose(self) -> np.ndarray:
        """The driven robot's true pose (3,) [m, m, rad]."""
        return self.sim.sims[self.driven].pose if self.worker is None else self._shown_at[2][self.driven]

    @property
    def truth_trail(self) -> Trail:
        """The driven robot's true path."""
        return self.truth_trails[self.driven]

    def trail(self, name: str) -> Trail:
        """The driven robot's estimate trail under filter ``name``."""
        return self.trails[name][self.driven]

    def belief(self, name: str) -> Belief | None:
        """The driven robot's belief under single-robot filter ``name``, to draw, through the
        runner's guard (time limit, types, shapes, finite values): None, and the filter
        switched off with the reason, when ``belief()`` raises, hangs or returns something
        that cannot be drawn. None for a team filter (its robots' estimates are drawn)."""
        if not self.filters_run.is_member(name):
            return None
        if self.worker is not None:  # read on the worker after the tick shown
            drawn = self._drawn()
            return None if drawn is None else drawn.beliefs[name][self.driven]
        tr = self.filters_run.members[self.driven].tracks[name]
        if tr.failed or tr.filter is None:
            return None
        # A filter changes only in a tick (commands included) or when it is replaced: the
        # belief read and checked once per tick serves every frame until the next (a 10k-
        # particle or 86,400-cell belief is copied and checked, about 0.2 ms a frame).
        hit = self._beliefs.get(name)
        if hit is not None and hit[0] == self.sim.tick and hit[1] is tr.filter:
            return hit[2]
        bel = self._guarded_read(name, tr.filter.belief, validate_belief, "belief(): ")
        if bel is not None:
            self._beliefs[name] = (self.sim.tick, tr.filter, bel)
        return bel

    def estimate(self, name: str) -> tuple[np.ndarray, np.ndarray] | None:
        """The driven robot's latest estimate (mean (3,), cov (3, 3)); before the first tick,
        the filter's initial belief (through the guard: None, and the filter switched off,
        when it is unusable)."""
        est = self.estimates(name)
        return None if est is None else (est[0][self.driven], est[1][self.driven])

    def estimates(self, name: str) -> tuple[np.ndarray, np.ndarray] | None:
        """Every robot's latest estimate under ``name``: (means (N, 3), covs (N, 3, 3)); before
        the first tick the filter's initial belief (through the guard: None, and the filter
        switched off, when it is unusable)."""
        if self.worker is not None:  # as of the tick shown
            return None if self._state is None else self._state.latest[name]
        return self._live_estimates(name)

    def _live_estimates(self, name: str) -> tuple[np.ndarray, np.ndarray] | None:
        """:meth:`estimates` read from the filters (not from the tick shown)."""
        latest = self.filters_run.latest(name)
        if latest is not None:
            return latest
        if self.filters_run.failed(name):
            return None
        if self.filters_run.is_member(name):
            means, covs = np.empty((self.n_robots, 3)), np.empty((self.n_robots, 3, 3))
            for i, runner in enumerate(self.filters_run.members):
                tr = runner.tracks[name]
                if tr.filter is None:
                    return None
                est = self._guarded_read(name, tr.filter.estimate, validate_estimate)
                if est is None:
                    return None
                means[i], covs[i] = est
            return means, covs
        f = team_filter_of(self.joint.tracks[name])
        if f is None:
            return None
        return self._guarded_read(name, f.estimates,
                                  partial(validate_team_estimates, n_robots=self.n_robots),
                                  "estimates(): ")

    def _guarded_read(self, name: str, call: Callable[[], object],
                      validate: Callable[[object], Any], raised_prefix: str = "") -> Any:
        """``validate(call())`` under the window's time limit; None, and the filter switched
        off with the reason, when the call raises, hangs or returns something unusable."""
        value, why, tb = call_guarded(call, WINDOW_STEP_LIMIT_S, cpu=True)
        if why is None:
            checked = validate(value)
            if not isinstance(checked, str):
                return checked
            why = checked if not raised_prefix.startswith("estimates") else raised_prefix + checked
        else:
            why = raised_prefix + why
        self._switch_off(name, why, tb)
        return None

    def _switch_off(self, name: str, why: str, tb: str = "") -> None:
        if self.worker is not None and self.worker.on_thread():  # shown with its tick
            self.filters_run.fail(name, why, tb, self._fail_time)
            return
        self.filters_run.fail(name, why, tb, self.sim.time)
        self._sync_status(name)

    def _sync_status(self, name: str) -> None:
        st = self.status[name]
        if self.worker is not None and self._state is not None:  # as of the tick shown
            st.failed = self._state.failed[name]
            st.warning = self._state.warnings[name][self.driven]
            return
        st.failed = self.filters_run.failed(name)
        st.warning = status_line(self.filters_run.track(name, self.driven))

    @property
    def filters(self) -> dict[str, object]:
        """The driven robot's working filter objects by name (a team filter's joint object);
        with a worker, what the window reads of them after the tick shown (``FilterFace``)."""
        if self.worker is not None:
            drawn = self._drawn()
            return {} if drawn is None else {n: f for n, f in drawn.faces[self.driven].items()
                                             if not self.status[n].failed}
        out: dict[str, object] = {}
        for n in self.names:
            tr = self.filters_run.track(n, self.driven)
            if tr.filter is not None:
                out[n] = tr.filter
        return out

    # --- the step view: predict, then update, of the last tick ------------------------------
    def _keep_priors(self) -> None:
        """Ask each robot's runner to keep the belief after predict of every Gaussian filter
        (one whose ``belief()`` is a GaussianBelief); the others' beliefs have no single
        ellipse."""
        for runner in self.filters_run.members:
            keep = set()
            for name, tr in runner.tracks.items():
                if tr.filter is None or tr.failed:
                    continue
                # a student's belief() may raise (or exit, or hang) before the first tick
                bel, why, _ = call_guarded(tr.filter.belief, WINDOW_STEP_LIMIT_S, cpu=True)
                if why is None and isinstance(bel, GaussianBelief):
                    keep.add(name)
            runner.keep_prior = frozenset(keep)

    def predict_update(self, name: str) -> tuple[tuple[np.ndarray, np.ndarray],
                                                  tuple[np.ndarray, np.ndarray]] | None:
        """The driven robot's last tick under a Gaussian filter: ``((mean, cov) after
        predict, (mean, cov) after update)`` [m, m, rad], or None (not Gaussian, a team
        filter, switched off, no tick yet)."""
        if not self.filters_run.is_member(name):
            return None
        runner = self.filters_run.members[self.driven]
        tr = runner.tracks.get(name)
        prior = runner.priors.get(name)
        if self.worker is not None:  # as of the tick shown
            drawn, state = self._drawn(), self._state
            prior = None if drawn is None else drawn.priors[self.driven].get(name)
            if (prior is None or state is None or state.failed[name] or name not in state.fresh
                    or (latest := state.latest[name]) is None):
                return None
            return prior, (latest[0][self.driven], latest[1][self.driven])
        if (tr is None or prior is None or tr.failed or self.last_step is None or not tr.ticks
                or tr.ticks[-1] != self.last_step.tick):
            return None
        return prior, (tr.means[-1], tr.covs[-1])

    def used_ids(self) -> set[int]:
        """The beacons in the driven robot's last tick's readings: the ones its update used."""
        if self.last_step is None:
            return set()
        return {int(i) for m in self.last_step.steps[self.driven].measurements for i in m.beacon_ids}

    # --- one tick -------------------------------------------------------------------------
    def tick(self) -> TeamStep:
        """Run one tick with the driven robot's command and the queued user commands. With a
        worker (:meth:`start_worker`) only the simulation's part runs here; the recording,
        the filters' part of the commands and the filters run on the worker, in order, and
        :meth:`collect` shows the ticks they finished."""
        control = self.next_control()
        cmds, self.pending = self.pending, []
        tick = self.sim.tick + 1
        recorded = (tick, self.driven, control, self.autopilot, self._shown + cmds)
        self._shown = []
        if self.worker is None:
            c0 = time.thread_time()
            if self.recorder is not None:
                self.recorder.record_tick(*recorded)
            self._apply(cmds)
            self.filter_cpu_s += time.thread_time() - c0
            step = self.sim.step({self.driven: control})
            self._steered(step)
            c0 = time.thread_time()
            self.filters_run.feed(step)
            outcome = self._filter_tick(step.tick)
            self.filter_cpu_s += time.thread_time() - c0
        else:
            time_s = self.sim.time
            commands_to_sim(cmds, self.sim)
            step = self.sim.step({self.driven: control})
            self._steered(step)
            self.worker.submit(partial(self._filter_job, recorded, cmds, time_s, step))
        if step.time <= HISTORY_S:
            self.steps.append(step)
        self.controls.append(control)
        if cmds:
            self.commands[tick] = cmds
        if self.worker is None:
            self._after(step, outcome)
        return step

    def _apply(self, cmds: list[dict]) -> None:
        """User commands, before the tick's step (``runs/user_commands``): a kidnap of its
        robot (a single robot's when it names none); resets of every robot's working filters
        (under the guard: one that fails is switched off) and of the team filters."""
        if not cmds:
            return
        for name in self._commands_to_filters(cmds, self.sim, self.sim.time):
            self._sync_status(name)
        if any(c["kind"] == "reset" for c in cmds):  # switched-off filters may be back on
            for name in self.names:
                self._sync_status(name)
        self._commands_shown(cmds)

    def _commands_to_filters(self, cmds: list[dict], sim: TeamSimulation | None,
                             time_s: float) -> list[str]:
        """The commands' part on the filters (and on ``sim`` unless None); the names of the
        filters whose reset failed."""
        failed = list(apply_to_run(cmds, sim, self.filters_run, WINDOW_STEP_LIMIT_S, time_s, cpu=True))
        if any(c["kind"] == "reset" for c in cmds):
            self._keep_priors()
        return failed

    def _commands_shown(self, cmds: list[dict]) -> None:
        """The commands' part on what is shown: a reset breaks the trails and starts the
        NEES windows afresh."""
        if any(c["kind"] in ("reset", "global_reset") for c in cmds):
            for trails in self.trails.values():
                for trail in trails:
                    trail.brk()
            for figures in self.robot_status.values():  # NEES judged afresh after a reset
                for st in figures:
                    st.clear_window()
            for st in self.status.values():
                st.clear_window()

    def _steered(self, step: TeamStep) -> None:
        """What a tick changes in the driving at once (the next tick's command depends on
        it): the robots' last commands; a bump stops the keyboard's robot."""
        for i, s in enumerate(step.steps):
            self.last_controls[i] = s.control
        if not self.autopilot and any(e.kind == "bump" for e in step.steps[self.driven].events):
            self.keyboard.v = 0.0  # the bumper stopped the robot: the command says so too

    def _filter_tick(self, tick: int, drawing: bool = False) -> FilterTick:
        """The filters just after ``tick`` (``runs/filter_snapshot``), read on the thread that
        fed them; ``drawing``: with what the window draws of them."""
        drawn = read_drawing(self.filters_run, self._switch_off) if drawing else None
        return filter_tick(self.filters_run, self.names, tick, self._live_estimates, drawn)

    def _after(self, step: TeamStep, outcome: FilterTick) -> None:
        """Show tick ``step`` with its filters ``outcome``: the readings, the trails, the
        figures (each estimate against the truth of its own tick), the listeners."""
        self.last_step = step
        self._state = outcome
        if outcome.drawing is not None:
            self._beliefs.clear()
        self._shown_at = (step.tick, step.time, np.array([s.true_pose for s in step.steps]))
        for i, s in enumerate(step.steps):
            seen = self._readings[i]
            for m in step.measurements(i):
                seen[m.sensor] = (step.tick, m)
            for sensor in list(seen):
                if step.tick - seen[sensor][0] >= self._every[i].get(sensor, 1):
                    del seen[sensor]
            if s.kidnapped:
                self.truth_trails[i].brk()
            self.truth_trails[i].add(s.true_pose)
            self.recent_events.extend(s.events)
        del self.recent_events[:-20]
        for name in self.names:
            self._sync_status(name)
            if self.status[name].failed or name not in outcome.fresh:
                continue
            latest = outcome.latest[name]
            if latest is None:
                continue
            means, covs = latest
            for i, s in enumerate(step.steps):
                self.trails[name][i].add(means[i])
                self.robot_status[name][i].measure(means[i], covs[i], s.true_pose, step.dt)
        if self.on_step:
            for listener in self.on_step:
                listener(step.steps[0])

    def readings(self, i: int | None = None) -> list[Measurement]:
        """Robot i's (default: the driven robot's) latest reading of each sensor still within
        its period."""
        return [m for _, m in self._readings[self.driven if i is None else i].values()]

    def beacon_readings(self, i: int) -> list[Measurement]:
        """Robot i's latest reading of each beacon sensor still within its period."""
        return [m for m in self.readings(i) if not m.kind.startswith("robot_")]

    def robot_readings(self, i: int) -> list[Measurement]:
        """Robot i's latest reading of each robot sensor still within its period (kind
        ``robot_range_bearing`` / ``robot_bearing``; ``beacon_ids`` are the robot IDs seen)."""
        return [m for m in self.readings(i) if m.kind.startswith("robot_")]

    def seen_ids(self, i: int | None = None) -> set[int]:
        """Beacon IDs in view of robot i (every robot's when None)."""
        robots = range(self.n_robots) if i is None else (i,)
        return {int(b) for k in robots for m in self.beacon_readings(k) for b in m.beacon_ids}

    def teammates_seen(self, i: int) -> list[str]:
        """Names of the robots robot i sees now, in team order."""
        ids = {int(b) for m in self.robot_readings(i) for b in m.beacon_ids}
        return [r.name for r in self.team.robots if r.id in ids]

    def clear_trails(self) -> None:
        """Forget every trail (truth and estimates), keep the current points."""
        for i, trail in enumerate(self.truth_trails):
            trail.clear()
            trail.add(self.poses[i])
        for name, trails in self.trails.items():
            est = self.estimates(name) if not self.status[name].failed else None
            for i, trail in enumerate(trails):
                trail.clear()
                if est is not None:
                    trail.add(est[0][i])

    def close(self) -> None:
        """Finish the worker's ticks (if the filters run on one), write the recording's end
        line and close it (if the session is recorded)."""
        self.stop_worker()
        if self.recorder is not None:
            self.recorder.close()
            self.recorder = None


def make_recorder(scenario: Scenario | TeamScenario, seed: int, specs: list[str],
                  params: dict[str, dict[str, Any]]) -> tuple[Recorder, Path]:
    """A recorder writing to ``recordings/<scenario>_<time>.jsonl``, and that path."""
    recorder = Recorder(Path(default_recording_path(scenario.name)), scenario, seed, list(specs),
                        params)
    return recorder, recorder.path  # (another name when that one was just taken)
