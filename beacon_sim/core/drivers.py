"""Drivers: what commands the robot when no one is at the keyboard.

Every driver has ``control(time, pose) -> Control``; it sees the true pose (the planner is
part of the world, not of a filter) and draws only from its own random generator.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from beacon_sim.core import portable_math as pm
from beacon_sim.core.angles import wrap
from beacon_sim.core.measurement_models import relative_bearing_scalar
from beacon_sim.core.types import Control
from beacon_sim.core.world import World


@dataclass(frozen=True)
class ConstantSpec:
    """Constant command: ``v`` [m/s], ``omega`` [rad/s]."""

    v: float = 0.0
    omega: float = 0.0
    kind = "constant"


@dataclass(frozen=True)
class CircleSpec:
    """Drive a circle of ``radius`` [m] at ``speed`` [m/s], counter-clockwise."""

    radius: float = 1.0
    speed: float = 0.2
    kind = "circle"


@dataclass(frozen=True)
class RandomGoalSpec:
    """Seed 000's planner: head for a random goal in the bounds; pick a new one on arrival.

    ``speed`` [m/s], ``gain`` [1/s] on the heading error, ``max_omega`` [rad/s],
    ``tolerance`` [m] to count a goal as reached, ``margin`` [m] kept from the walls.
    """

    speed: float = 0.3
    gain: float = 2.0
    max_omega: float = 1.5
    tolerance: float = 0.3
    margin: float = 0.5
    kind = "random_goal"


@dataclass(frozen=True)
class WaypointsSpec:
    """Visit ``points`` [[x, y], ...] in order, looping when ``loop`` is true."""

    points: tuple[tuple[float, float], ...] = ()
    speed: float = 0.3
    gain: float = 2.0
    max_omega: float = 1.5
    tolerance: float = 0.2
    loop: bool = True
    kind = "waypoints"


@dataclass(frozen=True)
class KeyboardSpec:
    """Driven from the keyboard in the window; headless runs get zero commands."""

    kind = "keyboard"


DriverSpec = ConstantSpec | CircleSpec | RandomGoalSpec | WaypointsSpec | KeyboardSpec


def steer_towards(pose, goal_xy, speed, gain, max_omega) -> Control:
    """Proportional steering to a point: slow down while the heading error is large."""
    dx, dy = goal_xy[0] - pose[0], goal_xy[1] - pose[1]
    err = wrap(relative_bearing_scalar(float(dx), float(dy), pose[2], portable=True))
    omega = float(min(max(gain * err, -max_omega), max_omega))  # np.clip of a float, without numpy
    v = speed * max(0.0, pm.cos1(float(err)))
    return Control(v, omega)


def arrived(goal, pose, tolerance: float) -> bool:
    """Whether ``pose`` (3,) is within ``tolerance`` [m] of ``goal`` (2,) (portable maths)."""
    return pm.hypot1(float(goal[0] - pose[0]), float(goal[1] - pose[1])) < tolerance


@dataclass
class Driver:
    """Runs a :class:`DriverSpec`. Holds the planner's state (current goal or waypoint)."""

    spec: DriverSpec
    world: World
    rng: np.random.Generator
    _goal: np.ndarray | None = field(default=None, init=False)
    _index: int = field(default=0, init=False)

    def control(self, time: float, pose: np.ndarray) -> Control:
        """The command for the step that starts at ``time`` [s] from the true ``pose``."""
        s = self.spec
        if isinstance(s, ConstantSpec):
            return Control(s.v, s.omega)
        if isinstance(s, CircleSpec):
            return Control(s.speed, s.speed / s.radius)
        if isinstance(s, RandomGoalSpec):
            if self._goal is None or arrived(self._goal, pose, s.tolerance):
                xmin, ymin, xmax, ymax = self.world.bounds
                self._goal = np.array([
                    self.rng.uniform(xmin + s.margin, xmax - s.margin),
                    self.rng.uniform(ymin + s.margin, ymax - s.margin),
                ])
            return steer_towards(pose, self._goal, s.speed, s.gain, s.max_omega)
        if isinstance(s, WaypointsSpec):
            if not s.points or self._index >= len(s.points):
                return Control(0.0, 0.0)
            goal = np.array(s.points[self._index], dtype=float)
            if arrived(goal, pose, s.tolerance):
                self._index += 1
                if s.loop:
                    self._index %= len(s.points)
                if self._index >= len(s.points):
                    return Control(0.0, 0.0)
                goal = np.array(s.points[self._index], dtype=float)
            return steer_towards(pose, goal, s.speed, s.gain, s.max_omega)
        return Control(0.0, 0.0)

    @property
    def goal(self) -> np.ndarray | None:
        """The current goal [m] of the random-goal or waypoint planner (None otherwise)."""
        if isinstance(self.spec, WaypointsSpec) and self.spec.points:
            return np.array(self.spec.points[self._index % len(self.spec.points)], dtype=float)
        return self._goal
