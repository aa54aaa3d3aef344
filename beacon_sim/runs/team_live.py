"""A live team session (issue 18), without pygame: the :class:`TeamSimulation`, the team
filters side by side under the guard of :class:`~beacon_sim.filters.team_runner.JointRunner`,
the keyboard's command for the driven robot (Tab switches which), user commands, trails and
the figures the team window shows.

Every tick goes the same way (:meth:`TeamSession.tick`): take the driven robot's command
(keyboard, or its own driver on autopilot), apply the user commands queued since the last
tick (a kidnap of the robot that was driven when it was asked, filter resets), step every
robot (the others follow their drivers), feed the team filters. The window only changes
the keyboard's state and the driven index between ticks, so the same scenario, seed and
key presses give the same run whatever the frame rate.

With a :class:`~beacon_sim.runs.recorder.TeamRecorder` (``play`` makes one unless
``--no-record``: :func:`make_team_recorder`) every tick is recorded before it runs: the
driven robot, its command and whether its driver chose it, the user commands; replayed by
``runs/team_replay.py``.

Memory is bounded: the runner keeps the last :data:`KEEP_ESTIMATES` estimates of each
filter, trails are capped (:class:`~beacon_sim.runs.scene.Trail`), and only the latest
reading of each sensor is kept for drawing.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from beacon_sim.core.drivers import KeyboardSpec
from beacon_sim.core.keyboard_drive import KeyboardDrive
from beacon_sim.core.schedule import tick_schedule
from beacon_sim.core.team import TeamSimulation, TeamStep
from beacon_sim.core.team_scenario import TeamScenario
from beacon_sim.core.types import Control, Measurement
from beacon_sim.filters.loading import WINDOW_BUILD_LIMIT_S
from beacon_sim.filters.runner import WINDOW_STEP_LIMIT_S, guarded_call, status_line
from beacon_sim.filters.team import initial_beliefs
from beacon_sim.filters.team_runner import (
    JointRunner,
    build_team_filters,
    team_filter_of,
    validate_team_estimates,
)
from beacon_sim.filters.team_specs import build_team_spec, team_filter_name
from beacon_sim.io.recording import default_recording_path
from beacon_sim.runs.live import taken_over
from beacon_sim.runs.recorder import TeamRecorder
from beacon_sim.runs.scene import FilterStatus, Trail

#: Estimates the runner keeps per team filter: the screen draws the latest; trails are
#: grown tick by tick, so nothing older is needed.
KEEP_ESTIMATES = 2
#: Points of each estimate's trail (one per team filter and robot): about 20 s of a robot
#: at 0.3 m/s, so that a dozen estimate trails do not bury the truth's (which keeps the
#: usual 6000).
ESTIMATE_TRAIL_POINTS = 300
#: User commands a team session understands (applied on the next tick; recorded as
#: ``io.recording.TEAM_COMMAND_KINDS``).
COMMAND_KINDS = ("kidnap", "reset", "toggle")


@dataclass
class TeamSession:
    """A team scenario, a seed and named team filters, advanced one tick at a time.

    Parameters
    ----------
    team : TeamScenario
    specs : list of str
        Team filter specs, as ``run`` takes them: names of
        ``beacon_sim.filters.team.TEAM_FILTERS`` or ``independent:F`` (every robot's own
        single-robot filter F, a student's too; see ``runs/team.build_team_spec``).
    seed : int, optional
        Defaults to the scenario's.
    params : dict, optional
        ``{filter_name: {param: value}}`` overrides (from ``--set``).
    recorder : TeamRecorder, optional
        Anything with ``record_tick(tick, driven, control, autopilot, commands)`` and
        ``close()`` (``runs/recorder.TeamRecorder``: the session written as it goes).
    """

    team: TeamScenario
    specs: list[str]
    seed: int | None = None
    params: dict[str, dict[str, Any]] = field(default_factory=dict)
    recorder: Any = None

    def __post_init__(self) -> None:
        team = self.team
        self.seed = team.seed if self.seed is None else int(self.seed)
        seed = self.seed
        specs = {team_filter_name(s): s for s in self.specs}  # name shown -> spec
        self.names = list(specs)
        built, why = build_team_filters(
            self.names, lambda n: build_team_spec(specs[n], team, self.params.get(n), seed),
            WINDOW_BUILD_LIMIT_S)
        self.runner = JointRunner(built, len(team.robots), step_limit_s=WINDOW_STEP_LIMIT_S,
                                       keep=KEEP_ESTIMATES)
        for name, reason in why.items():
            self.runner.tracks[name].failed = f"could not be built: {reason}"
        if self.recorder is not None and hasattr(self.recorder, "attach"):
            self.recorder.attach(self.runner)  # the recording stores the filters' settings
        self.sim = TeamSimulation(team, seed)
        self.robot_names = [r.name for r in team.robots]
        self.driven = 0
        self.keyboard = KeyboardDrive(team.keyboard)
        self.autopilot = False
        self.pending: list[dict] = []
        self._shown: list[dict] = []  # show / hide since the last tick: recorded with the next
        self.visible = {n: True for n in self.names}
        self.last_step: TeamStep | None = None
        self.last_controls: list[Control] = [Control() for _ in team.robots]
        # robot index -> sensor name -> (tick, reading): the latest reading within its period
        self._readings: list[dict[str, tuple[int, Measurement]]] = [{} for _ in team.robots]
        self._every = [tick_schedule(r.scenario, r.robot_sensors).every for r in team.robots]
        self.truth_trails = [Trail() for _ in team.robots]
        for tr, r in zip(self.truth_trails, team.robots, strict=True):
            tr.add(r.scenario.initial_pose)
        self.trails = {n: [Trail(max_points=ESTIMATE_TRAIL_POINTS) for _ in team.robots]
                       for n in self.names}
        self.status = {n: FilterStatus(n) for n in self.names}
        self.robot_status = {n: [FilterStatus(f"{n}/{r}") for r in self.robot_names]
                             for n in self.names}
        for n in self.names:
            self._sync_status(n)
            est = self.estimates(n)
            if est is not None:
                for trail, mean in zip(self.trails[n], est[0], strict=True):
                    trail.add(mean)

    # --- what the window reads ------------------------------------------------------------
    @property
    def scenario(self) -> TeamScenario:
        """The team scenario (the window reads its ``name``, ``dt`` and ``world``)."""
        return self.team

    @property
    def n_robots(self) -> int:
        return len(self.team.robots)

    @property
    def tick_count(self) -> int:
        return self.sim.tick

    @property
    def time(self) -> float:
        return self.sim.time

    @property
    def poses(self) -> np.ndarray:
        """Every robot's true pose now, shape (N, 3) [m, m, rad]."""
        return self.sim.poses

    @property
    def true_pose(self) -> np.ndarray:
        """The driven robot's true pose (3,) (a click-kidnap keeps its heading)."""
        return self.sim.sims[self.driven].pose

    @property
    def driven_name(self) -> str:
        return self.robot_names[self.driven]

    def estimates(self, name: str) -> tuple[np.ndarray, np.ndarray] | None:
        """Team filter ``name``'s latest ``(means (N, 3), covs (N, 3, 3))``, every robot's
        marginal of the filter's belief; before the first tick its initial belief (through
        the guard: None, and the filter switched off, when it is unusable)."""
        tr = self.runner.tracks[name]
        if tr.means:
            return tr.means[-1], tr.covs[-1]
        f = team_filter_of(tr)
        if tr.failed or f is None:
            return None
        value, why, tb = guarded_call(f.estimates, WINDOW_STEP_LIMIT_S)
        if why is None:
            checked = validate_team_estimates(value, self.n_robots)
            if not isinstance(checked, str):
                return checked
            why = checked
        self.runner.fail(name, f"estimates(): {why}", tb, self.sim.time)
        self._sync_status(name)
        return None

    def beacon_readings(self, i: int) -> list[Measurement]:
        """Robot i's latest reading of each beacon sensor still within its period."""
        return [m for _, m in self._readings[i].values() if not m.kind.startswith("robot_")]

    def robot_readings(self, i: int) -> list[Measurement]:
        """Robot i's latest reading of each robot sensor still within its period (kind
        ``robot_range_bearing`` / ``robot_bearing``; ``beacon_ids`` are the robot IDs seen)."""
        return [m for _, m in self._readings[i].values() if m.kind.startswith("robot_")]

    def seen_ids(self, i: int | None = None) -> set[int]:
        """Beacon IDs in view of robot i (every robot's when None)."""
        robots = range(self.n_robots) if i is None else (i,)
        return {int(b) for k in robots for m in self.beacon_readings(k) for b in m.beacon_ids}

    def teammates_seen(self, i: int) -> list[str]:
        """Names of the robots robot i sees now, in team order."""
        ids = {int(b) for m in self.robot_readings(i) for b in m.beacon_ids}
        return [r.name for r in self.team.robots if r.id in ids]

    def robot_index(self, robot_id: int) -> int | None:
        for k, r in enumerate(self.team.robots):
            if r.id == robot_id:
                return k
        return None

    # --- driving --------------------------------------------------------------------------
    @property
    def has_autopilot(self) -> bool:
        """Whether the driven robot has a driver of its own to hand over to (M)."""
        return not isinstance(self.team.robots[self.driven].scenario.driver, KeyboardSpec)

    def next_control(self) -> Control:
        """The driven robot's command for the next tick."""
        if self.autopilot:
            sim = self.sim.sims[self.driven]
            return sim.driver.control(sim.time, sim.pose)
        return self.keyboard.control

    @property
    def drive_mode(self) -> str:
        return "AUTOPILOT (M)" if self.autopilot else "keyboard WASD, X stop"

    def drive(self, key: str) -> None:
        """W/S/A/D/X on the driven robot's command; driving by hand ends the autopilot."""
        if self.autopilot:
            self.autopilot = False
            self._take_over()
        self.keyboard.press(key)

    def toggle_autopilot(self) -> None:
        self.autopilot = self.has_autopilot and not self.autopilot
        if not self.autopilot:
            self._take_over()

    def _take_over(self) -> None:
        """The keyboard starts from the driven robot's last command (no jolt), rounded to the
        keyboard's steps (see :func:`~beacon_sim.runs.live.taken_over`)."""
        self.keyboard.v, self.keyboard.omega = taken_over(self.last_controls[self.driven],
                                                          self.keyboard.limits)

    def next_robot(self, step: int = 1) -> str:
        """Tab: drive the next robot (the one driven so far goes back to its driver); the
        keyboard takes over the new one's last command. Returns its name."""
        self.driven = (self.driven + step) % self.n_robots
        if self.autopilot and not self.has_autopilot:
            self.autopilot = False
        if not self.autopilot:
            self._take_over()
        return self.driven_name

    def command(self, cmd: dict) -> None:
        """Queue a user command for the next tick: ``kidnap`` (of the robot driven now, to
        ``pose`` or a random pose), ``reset`` (every team filter to the initial beliefs);
        ``toggle`` shows / hides a filter at once (display only)."""
        kind = cmd.get("kind")
        if kind not in COMMAND_KINDS:
            raise ValueError(f"a team session has no command {kind!r}")
        if kind == "toggle":
            if cmd.get("filter") in self.visible:
                self.visible[cmd["filter"]] = not self.visible[cmd["filter"]]
                self._shown.append({"kind": "toggle", "filter": cmd["filter"]})
            return
        self.pending.append({**cmd, "robot": self.driven})

    # --- one tick -------------------------------------------------------------------------
    def tick(self) -> TeamStep:
        """Run one team tick with the driven robot's command and the queued user commands."""
        cmds, self.pending = self.pending, []
        control = self.next_control()
        if self.recorder is not None:
            self.recorder.record_tick(self.sim.tick + 1, self.driven, control, self.autopilot,
                                      self._shown + cmds)
        self._shown = []
        for cmd in cmds:
            if cmd["kind"] == "kidnap":
                self.sim.sims[cmd["robot"]].request_kidnap(cmd.get("pose"))
            elif cmd["kind"] == "reset":
                self._reset_filters()
        step = self.sim.step({self.driven: control})
        self.runner.feed(step.tick, step.time, [s.control for s in step.steps], step.dt,
                         [step.measurements(i) for i in range(len(step.steps))])
        self._after(step)
        return step

    def _reset_filters(self) -> None:
        """Every working team filter back to the scenario's initial beliefs (guarded)."""
        reset_team_filters(self.runner, self.team, WINDOW_STEP_LIMIT_S, self.sim.time)
        for name in self.names:
            for trail in self.trails[name]:
                trail.brk()

    def _after(self, step: TeamStep) -> None:
        self.last_step = step
        for i, s in enumerate(step.steps):
            self.last_controls[i] = s.control
            seen = self._readings[i]
            for m in step.measurements(i):
                seen[m.sensor] = (step.tick, m)
            for sensor in list(seen):
                if step.tick - seen[sensor][0] >= self._every[i].get(sensor, 1):
                    del seen[sensor]
            if s.kidnapped:
                self.truth_trails[i].brk()
            self.truth_trails[i].add(s.true_pose)
        if not self.autopilot and any(e.kind == "bump" for e in step.steps[self.driven].events):
            self.keyboard.v = 0.0  # the bumper stopped the robot: the command says so too
        truth = step.true_poses
        for name, tr in self.runner.tracks.items():
            self._sync_status(name)
            if tr.failed or not tr.ticks or tr.ticks[-1] != step.tick:
                continue
            means, covs = tr.means[-1], tr.covs[-1]
            for i in range(self.n_robots):
                self.trails[name][i].add(means[i])
                self.robot_status[name][i].measure(means[i], covs[i], truth[i])

    def _sync_status(self, name: str) -> None:
        tr = self.runner.tracks[name]
        st = self.status[name]
        st.failed = tr.failed
        st.warning = status_line(tr)

    def clear_trails(self) -> None:
        """Forget every trail (truth and estimates), keep the current points."""
        for i, tr in enumerate(self.truth_trails):
            tr.clear()
            tr.add(self.poses[i])
        for name, trails in self.trails.items():
            est = self.estimates(name) if not self.status[name].failed else None
            for i, tr in enumerate(trails):
                tr.clear()
                if est is not None:
                    tr.add(est[0][i])

    def close(self) -> None:
        """Write the recording's end line and close it (if the session is recorded)."""
        if self.recorder is not None:
            self.recorder.close()
            self.recorder = None


def reset_team_filters(runner: JointRunner, team: TeamScenario, limit_s: float | None,
                       time_s: float) -> None:
    """The ``reset`` user command: every working team filter of ``runner`` back to the
    scenario's initial beliefs, under the guard (one that fails is switched off), the same
    live and on replay."""
    beliefs = initial_beliefs(team)
    for name, tr in runner.tracks.items():
        f = team_filter_of(tr)
        if tr.failed or f is None:
            continue
        _, why, tb = guarded_call(partial(f.reset, beliefs), limit_s)
        if why is not None:
            runner.fail(name, f"reset: {why}", tb, time_s)


def make_team_recorder(team: TeamScenario, seed: int, specs: list[str],
                       params: dict[str, dict[str, Any]]) -> tuple[TeamRecorder, Path]:
    """A team recorder writing to ``recordings/<scenario>_<time>.jsonl``, and that path."""
    recorder = TeamRecorder(Path(default_recording_path(team.name)), team, seed, list(specs), params)
    return recorder, recorder.path  # (another name when that one was just taken)


__all__ = ["KEEP_ESTIMATES", "TeamSession", "make_team_recorder", "reset_team_filters"]
