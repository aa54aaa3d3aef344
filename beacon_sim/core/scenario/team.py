"""A scenario over N robots: :class:`TeamScenario` (the shared world and clock, and the
robots), :class:`TeamRobot` (one robot: its ID, its own single-robot :class:`Scenario` and
the sensors that see the other robots) and :class:`RobotSensorSpec`.

Every run takes a :class:`TeamScenario`: a single-robot scenario is a team of one
(:func:`team_of_one`, ``solo``), so a run, its evaluation and its bound are written once
over N robots. The file format is ``team_parser.py``'s.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

from beacon_sim.core.keyboard_drive import KeyboardLimits
from beacon_sim.core.scenario.model import Scenario, ScenarioHeader
from beacon_sim.core.sensors import SensorNoise, SensorReach

#: Most robots in a team.
MAX_ROBOTS = 100
#: Team filters a team scenario runs by default.
DEFAULT_TEAM_FILTERS = ("independent", "centralised", "decentralised", "ci")


@dataclass(frozen=True)
class RobotSensorSpec(SensorReach):
    """A sensor that measures the other robots of the team.

    kind : ``robot_range_bearing`` (range [m] and bearing [rad]) or ``robot_bearing``; the
    reach (period, range, field of view, detection) as a beacon sensor's. noise:
    ``range_std`` [m], ``bearing_std`` [rad].
    """

    noise: SensorNoise = field(default_factory=SensorNoise)

    def reading_std(self) -> tuple[float, ...]:
        """Standard deviations of one reading: ``(sb,)`` or ``(sr, sb)``."""
        if self.kind == "robot_bearing":
            return (self.noise.bearing_std,)
        return (self.noise.range_std, self.noise.bearing_std)


@dataclass(frozen=True)
class TeamRobot:
    """One robot of a team: its ID, its own single-robot :class:`Scenario` (pose, noise,
    beacon sensors, driver, initial belief, the model the filters are told) and its robot
    sensors (true noise and the noise the filters are told)."""

    name: str
    id: int
    scenario: Scenario
    robot_sensors: tuple[RobotSensorSpec, ...] = ()
    model_robot_sensors: tuple[RobotSensorSpec, ...] = ()


@dataclass(frozen=True)
class TeamScenario(ScenarioHeader):
    """A validated scenario over N robots: the shared world and clock, and the robots."""

    keyboard: KeyboardLimits
    robots: tuple[TeamRobot, ...]
    default_filters: tuple[str, ...] = DEFAULT_TEAM_FILTERS
    filter_params: dict[str, dict[str, Any]] = field(default_factory=dict)
    #: Made from a single-robot document (:func:`team_of_one`): its one robot's simulation
    #: draws from the run's own seed, so its truth is the single-robot run's, bit for bit.
    solo: bool = False

    @property
    def ids(self) -> tuple[int, ...]:
        return tuple(r.id for r in self.robots)

    @property
    def n_robots(self) -> int:
        return len(self.robots)

    def with_changes(self, **changes) -> TeamScenario:
        return replace(self, **changes)


def team_of_one(scenario: Scenario) -> TeamScenario:
    """A single-robot scenario as a team of one robot (ID 1, named ``robot``): the same
    world, clock, keyboard, default filters and filter settings; the robot's own
    :class:`Scenario` is ``scenario`` itself, and its simulation uses the run's seed
    (``solo``), so a team-of-one run is the single-robot run bit for bit."""
    robot = TeamRobot(name="robot", id=1, scenario=scenario)
    return TeamScenario(
        name=scenario.name, description=scenario.description, source=scenario.source,
        dt=scenario.dt, duration=scenario.duration, seed=scenario.seed, world=scenario.world,
        keyboard=scenario.keyboard, robots=(robot,), default_filters=scenario.default_filters,
        filter_params=dict(scenario.filter_params), solo=True)


def as_team(scenario: Scenario | TeamScenario) -> TeamScenario:
    """``scenario`` as a team: a team scenario unchanged, a single-robot one as a team of one."""
    return scenario if isinstance(scenario, TeamScenario) else team_of_one(scenario)
