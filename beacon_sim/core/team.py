"""Several robots in one world: each robot runs the single-robot
:class:`~beacon_sim.core.simulation.Simulation` (truth, beacon sensors, driver) with its own
seed, and robot sensors read the others after every robot has moved.

Order of a team tick: every robot steps (its driver or the given command, its motion
noise, its beacon sensors, in the order of the file); then, at the new true poses, every
robot sensor due on the tick reads the other robots in range and view (a Bernoulli draw
with ``detection_prob`` each). Robots do not collide with each other.

Random streams: robot i's simulation uses the seed :func:`robot_seed` ``(seed, id)`` (a
team of one made from a single-robot file, ``TeamScenario.solo``, uses ``seed`` itself: its
run is the single-robot run bit for bit); each
robot sensor has its own stream (``stream(seed, "robot_sensor", "<id>/<name>")``) and draws
a fixed number of numbers per reading, so adding a robot sensor or a filter changes no
other robot's truth.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, replace

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.scenario import RobotSensorSpec, TeamScenario
from beacon_sim.core.schedule import tick_schedule
from beacon_sim.core.simulation import Simulation, scenario_with_slip
from beacon_sim.core.streams import stream
from beacon_sim.core.team_models import ROBOT_MEASUREMENT_DIMS, relative_range_bearing
from beacon_sim.core.types import Control, Measurement, Step


def robot_seed(seed: int, robot_id: int) -> int:
    """The seed of robot ``robot_id``'s own simulation in a team run with ``seed``."""
    ss = np.random.SeedSequence(int(seed), spawn_key=(0x7EA4, int(robot_id)))
    return int(ss.generate_state(1, dtype=np.uint32)[0])


@dataclass(frozen=True, eq=False)
class TeamStep:
    """One team tick: each robot's :class:`Step` (true pose, command, beacon readings,
    events) and each robot's robot-sensor readings (``Measurement`` of kind
    ``robot_range_bearing`` / ``robot_bearing`` whose ``beacon_ids`` are the robot IDs seen)."""

    tick: int
    time: float
    dt: float
    steps: tuple[Step, ...]
    robot_readings: tuple[tuple[Measurement, ...], ...]

    def measurements(self, i: int) -> tuple[Measurement, ...]:
        """Every reading of robot i on this tick: beacon readings, then robot readings."""
        return self.steps[i].measurements + self.robot_readings[i]

    @property
    def true_poses(self) -> np.ndarray:
        """True poses after the tick, shape (N, 3)."""
        return np.array([s.true_pose for s in self.steps])


def sense_robots(spec: RobotSensorSpec, observer: int, poses: np.ndarray, ids: tuple[int, ...],
                 rng: np.random.Generator) -> Measurement | None:
    """One reading of robot sensor ``spec`` on robot index ``observer`` at the true ``poses``
    (N, 3); None when no robot is detected. Draws 3 (N - 1) numbers whatever is seen."""
    n = len(ids)
    d = ROBOT_MEASUREMENT_DIMS[spec.kind]
    u = rng.random(n)
    noise = rng.standard_normal((n, 2))
    me = poses[observer]
    rows, seen = [], []
    for j in range(n):
        if j == observer:
            continue
        rb = relative_range_bearing(me, poses[j])
        if rb[0] > spec.max_range or (spec.fov < 2 * math.pi and abs(rb[1]) > 0.5 * spec.fov):
            continue
        if u[j] >= spec.detection_prob:
            continue
        z = rb + noise[j] * np.array([spec.noise.range_std, spec.noise.bearing_std])
        z[0] = abs(z[0])
        z[1] = wrap(float(z[1]))
        rows.append(z[2 - d:])
        seen.append(ids[j])
    if not rows:
        return None
    return Measurement(spec.name, spec.kind, np.array(rows).reshape(-1, d), np.array(seen, dtype=np.int64))


class TeamSimulation:
    """Runs a :class:`TeamScenario` with a seed; ``step(controls)`` -> :class:`TeamStep`."""

    def __init__(self, team: TeamScenario, seed: int | None = None):
        self.team = team
        self.seed = team.seed if seed is None else int(seed)
        self.dt = team.dt
        self.tick = 0
        self.sims = [Simulation(r.scenario, self.seed if team.solo else robot_seed(self.seed, r.id))
                     for r in team.robots]
        self.ids = team.ids
        self._rngs = [{s.name: stream(self.seed, "robot_sensor", f"{r.id}/{s.name}")
                       for s in r.robot_sensors} for r in team.robots]
        self._schedules = [tick_schedule(r.scenario, r.robot_sensors) for r in team.robots]
        self._hash = hashlib.sha256()

    @property
    def time(self) -> float:
        return self.tick * self.dt

    @property
    def poses(self) -> np.ndarray:
        """True poses now, shape (N, 3)."""
        return np.array([s.pose for s in self.sims])

    @property
    def truth_checksum(self) -> str:
        """SHA-256 (16 hex digits) over the robots' true poses, tick by tick; a team of one
        (``solo``) gives its robot's own, the single-robot run's checksum."""
        if self.team.solo:
            return self.sims[0].truth_checksum
        return self._hash.hexdigest()[:16]

    @property
    def readings_checksum(self) -> str:
        """A team of one's readings checksum (the single-robot run's); a team's readings are
        hashed by the recorder (``runs/recorder.TeamReadingsHash``)."""
        if not self.team.solo:
            raise AttributeError("a team's readings checksum is the recorder's")
        return self.sims[0].readings_checksum

    def step(self, controls: dict[int, Control] | None = None) -> TeamStep:
        """Advance every robot one tick. ``controls`` maps a robot index to the command it
        gets (the keyboard's robot); the others follow their drivers."""
        controls = controls or {}
        if self.team.solo:  # a team of one: its robot's Step, nothing else to hash or read
            step = self.sims[0].step(controls.get(0))
            self.tick += 1
            return TeamStep(self.tick, self.tick * self.dt, self.dt, (step,), ((),))
        steps = tuple(sim.step(controls.get(i)) for i, sim in enumerate(self.sims))
        self.tick += 1
        k = self.tick
        poses = np.array([s.true_pose for s in steps])
        self._hash.update(poses.tobytes())
        readings: list[tuple[Measurement, ...]] = []
        for i, robot in enumerate(self.team.robots):
            mine: list[Measurement] = []
            for spec in robot.robot_sensors:
                if not self._schedules[i].due(spec.name, k):
                    continue
                m = sense_robots(spec, i, poses, self.ids, self._rngs[i][spec.name])
                if m is not None:
                    mine.append(m)
            readings.append(tuple(mine))
        return TeamStep(k, k * self.dt, self.dt, steps, tuple(readings))

    def run(self, duration: float) -> list[TeamStep]:
        return [self.step() for _ in range(round(duration / self.dt))]


def team_with_slip(team: TeamScenario, model: str) -> TeamScenario:
    """``team`` with every robot's motion noise under the slip model ``model`` (see
    :func:`~beacon_sim.core.simulation.scenario_with_slip`)."""
    return replace(team, robots=tuple(replace(r, scenario=scenario_with_slip(r.scenario, model))
                                      for r in team.robots))
