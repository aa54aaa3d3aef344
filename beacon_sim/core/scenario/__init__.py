"""Scenario files (TOML) parsed into frozen dataclasses and validated at load (a module of
each idea below; this package re-exports their names, so ``from beacon_sim.core.scenario
import X`` keeps working).

Every error names the file, the key path, the bad value and what was expected; unknown
keys are errors with a "did you mean". The keys, units and defaults are documented in
docs/scenarios.md.

- ``model.py``: ``Scenario``, ``InitialBelief``, ``ScenarioError``;
- ``limits.py``: the ranges every number must lie in;
- ``toml_files.py``: a user's TOML file read safely;
- ``keys.py``: the keys each table may hold;
- ``table.py``: one table read key by key, with the key path for the error;
- ``parser.py``: the document parsed into a ``Scenario``; a scenario found and loaded;
- ``team.py``: ``TeamScenario``, a scenario over N robots (every run takes one; a
  single-robot scenario is a team of one, ``team_of_one``);
- ``team_parser.py``: the ``[[robots]]`` file parsed into a ``TeamScenario``, and
  ``load_any_scenario``, which reads any scenario file as a team.
"""

from beacon_sim.core.scenario.keys import RANGE_MODEL_KEYS, generic_path, keys_at
from beacon_sim.core.scenario.limits import (
    MAX_BEACONS,
    MAX_BEAMS,
    MAX_CLUTTER_RATE,
    MAX_COORD,
    MAX_DT,
    MAX_EVENT_TICKS,
    MAX_EVENTS,
    MAX_FRAC,
    MAX_INT_DIGITS,
    MAX_NESTING,
    MAX_SCENARIO_BYTES,
    MAX_SENSORS,
    MAX_SLAM_BEACONS,
    MAX_SPEED,
    MAX_STD,
    MAX_TICKS,
    MAX_TURN,
    MAX_WALL_POINTS,
    MIN_DT,
    MIN_SENSOR_STD,
    MIN_WORLD_SIDE,
)
from beacon_sim.core.scenario.model import InitialBelief, Scenario, ScenarioError, ScenarioHeader
from beacon_sim.core.scenario.parser import load_scenario, parse_scenario, resolve_scenario_path, sensor_noise
from beacon_sim.core.scenario.table import Table, Vec3, Vec4, finite_in
from beacon_sim.core.scenario.team import (
    DEFAULT_TEAM_FILTERS,
    MAX_ROBOTS,
    RobotSensorSpec,
    TeamRobot,
    TeamScenario,
    as_team,
    team_of_one,
)
from beacon_sim.core.scenario.team_parser import (
    ROBOT_KEYS,
    is_team_document,
    is_team_scenario,
    load_any_scenario,
    load_team_scenario,
    parse_any_scenario,
    parse_team_scenario,
    resolve_team_path,
    shipped_team_scenarios,
)
from beacon_sim.core.scenario.toml_files import (
    check_document,
    document_shape,
    env_limit,
    parse_toml_text,
    read_toml,
    read_user_toml,
)

__all__ = [
    "DEFAULT_TEAM_FILTERS",
    "MAX_BEACONS",
    "MAX_BEAMS",
    "MAX_CLUTTER_RATE",
    "MAX_COORD",
    "MAX_DT",
    "MAX_EVENTS",
    "MAX_EVENT_TICKS",
    "MAX_FRAC",
    "MAX_INT_DIGITS",
    "MAX_NESTING",
    "MAX_ROBOTS",
    "MAX_SCENARIO_BYTES",
    "MAX_SENSORS",
    "MAX_SLAM_BEACONS",
    "MAX_SPEED",
    "MAX_STD",
    "MAX_TICKS",
    "MAX_TURN",
    "MAX_WALL_POINTS",
    "MIN_DT",
    "MIN_SENSOR_STD",
    "MIN_WORLD_SIDE",
    "RANGE_MODEL_KEYS",
    "ROBOT_KEYS",
    "InitialBelief",
    "RobotSensorSpec",
    "Scenario",
    "ScenarioError",
    "ScenarioHeader",
    "Table",
    "TeamRobot",
    "TeamScenario",
    "Vec3",
    "Vec4",
    "as_team",
    "check_document",
    "document_shape",
    "env_limit",
    "finite_in",
    "generic_path",
    "is_team_document",
    "is_team_scenario",
    "keys_at",
    "load_any_scenario",
    "load_scenario",
    "load_team_scenario",
    "parse_any_scenario",
    "parse_scenario",
    "parse_team_scenario",
    "parse_toml_text",
    "read_toml",
    "read_user_toml",
    "resolve_scenario_path",
    "resolve_team_path",
    "sensor_noise",
    "shipped_team_scenarios",
    "team_of_one",
]
