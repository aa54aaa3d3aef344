"""What a scenario is once loaded: the frozen dataclasses ``Scenario`` and ``InitialBelief``,
and ``ScenarioError`` (one line naming the file, the key, the value and what was expected)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

from beacon_sim.core import arguments
from beacon_sim.core.drivers import DriverSpec
from beacon_sim.core.events import Event
from beacon_sim.core.keyboard_drive import KeyboardLimits
from beacon_sim.core.motion import MotionNoise
from beacon_sim.core.scenario.limits import MAX_DT, MAX_TICKS, MIN_DT
from beacon_sim.core.sensors import SensorSpec
from beacon_sim.core.world import World
from beacon_sim.errors import BeaconSimError


class ScenarioError(BeaconSimError):
    """A scenario file is missing, unreadable or invalid. The message is one line."""


@dataclass(frozen=True)
class InitialBelief:
    """The filters' initial belief: a Gaussian around ``mean`` with ``std`` [m, m, rad], or
    uniform over the world (``global_`` true, key ``global`` in the file)."""

    mean: tuple[float, float, float]
    std: tuple[float, float, float] = (0.1, 0.1, 0.05)
    global_: bool = False


@dataclass(frozen=True)
class ScenarioHeader:
    """What every scenario has, of one robot or a team (``team.TeamScenario``): its name,
    description and source file, the clock (``dt`` [s] per tick, ``duration`` [s], ``seed``)
    and the world."""

    name: str
    description: str
    source: str
    dt: float
    duration: float
    seed: int
    world: World


@dataclass(frozen=True)
class Scenario(ScenarioHeader):
    """A complete, validated scenario of one robot. See docs/scenarios.md for every key."""

    initial_pose: tuple[float, float, float]
    robot_radius: float
    motion_noise: MotionNoise
    sensors: tuple[SensorSpec, ...]
    driver: DriverSpec
    keyboard: KeyboardLimits
    events: tuple[Event, ...]
    initial_belief: InitialBelief
    model_motion_noise: MotionNoise
    model_sensors: tuple[SensorSpec, ...]
    default_filters: tuple[str, ...] = ("ekf", "dead_reckoning")
    filter_params: dict[str, dict[str, Any]] = field(default_factory=dict)
    #: False when ``[model] map = "unknown"``: the filters are not told where the beacons
    #: are (SLAM), except the anchors (``anchor = true`` on a beacon).
    map_known: bool = True
    anchor_ids: tuple[int, ...] = ()

    @property
    def filter_world(self) -> World:
        """The world as the filters are told it: every beacon on a known map; on an unknown
        one (SLAM, docs/slam.md) only the anchors, the bounds unchanged."""
        if self.map_known:
            return self.world
        keep = set(self.anchor_ids)
        return World(bounds=self.world.bounds,
                      beacons=tuple(b for b in self.world.beacons if b.id in keep))

    def sensor(self, name: str) -> SensorSpec:
        for s in self.sensors:
            if s.name == name:
                return s
        raise KeyError(name)

    def with_changes(self, **changes) -> Scenario:
        """A copy with some fields replaced (e.g. ``seed``); ``dt``, ``duration`` and
        ``seed`` are checked as in a file (core/arguments.py), a bad one is a ScenarioError."""
        new = replace(self, **changes)
        if {"dt", "duration", "seed"} & set(changes):
            arguments.check_tick(new.dt, MIN_DT, MAX_DT, "dt=", ScenarioError)
            arguments.check_duration(new.duration, new.dt, MAX_TICKS, "duration=", ScenarioError)
            arguments.check_seed(new.seed, "seed=", ScenarioError)
        return new


__all__ = ["InitialBelief", "Scenario", "ScenarioError", "ScenarioHeader"]
