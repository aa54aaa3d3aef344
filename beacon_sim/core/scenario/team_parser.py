"""The team file format: ``[[robots]]`` in one world, parsed into a
:class:`~beacon_sim.core.scenario.team.TeamScenario`; and the one entry that reads any
scenario file as a team (:func:`load_any_scenario`, :func:`parse_any_scenario`).

A team file has the single-robot file's top-level keys (``name``, ``description``, ``dt``,
``duration``, ``seed``, ``[world]``, ``[keyboard]``, ``default_filters``, ``[filters.*]``)
and, instead of ``[robot]``, ``[[sensors]]``, ``[driver]``, ``[initial_belief]`` and
``[model]``, an array ``[[robots]]`` whose entries hold each robot's own::

    [[robots]]
    name = "A"                 # unique; default "robot1", "robot2", ...
    id = 1                     # unique positive integer: what robot sensors report
    initial_pose = [x, y, theta]
    radius = 0.2
    motion_noise = { ... }     # as [robot].motion_noise
    driver = { kind = ... }    # as [driver]
    initial_belief = { std = [...] }
    model = { motion_noise = {...}, sensors = { NAME = {...} } }
    [[robots.sensors]]         # beacon sensors as [[sensors]], or a robot sensor:
    kind = "robot_range_bearing"   # or "robot_bearing": sees the other robots
    name, period, max_range, fov, detection_prob, range_std, bearing_std

Each robot is validated by the single-robot parser (``parser.py``) on a document made of
the shared keys and that robot's keys, so every check and message is the same; the key
paths in messages are rewritten to ``robots[i]....``. A single-robot file is not touched by
any of this (``load_scenario`` rejects ``robots``).
"""

from __future__ import annotations

import math
import re
from dataclasses import replace
from pathlib import Path
from typing import Any

from beacon_sim.core.resources import scenario_dir
from beacon_sim.core.scenario.limits import MAX_SENSORS
from beacon_sim.core.scenario.model import ScenarioError
from beacon_sim.core.scenario.parser import (
    load_scenario,
    parse_scenario,
    resolve_scenario_path,
    sensor_head,
    sensor_noise,
)
from beacon_sim.core.scenario.table import Table
from beacon_sim.core.scenario.team import (
    DEFAULT_TEAM_FILTERS,
    MAX_ROBOTS,
    RobotSensorSpec,
    TeamRobot,
    TeamScenario,
    team_of_one,
)
from beacon_sim.core.scenario.toml_files import read_toml
from beacon_sim.core.sensors import SensorNoise
from beacon_sim.core.team_models import ROBOT_MEASUREMENT_DIMS

#: Keys of one ``[[robots]]`` entry.
ROBOT_KEYS = {"name", "id", "initial_pose", "radius", "motion_noise", "driver", "initial_belief",
              "model", "sensors"}
_SHARED_KEYS = ("name", "description", "dt", "duration", "seed", "world", "keyboard",
                "default_filters", "filters")
_SINGLE_ONLY = ("robot", "sensors", "driver", "initial_belief", "model", "events")
#: What a team scenario's ``default_filters`` may name: a team filter, or ``independent:``
#: with a built-in filter or an entry point, optionally labelled; never a file or a module
#: (a shared file must not run code: only the command line and the API may name code).
_DATA_TEAM_FILTER = re.compile(
    r"^(?:[A-Za-z0-9_][A-Za-z0-9_.'+-]{0,63}=)?(?:independent:)?[A-Za-z0-9_][A-Za-z0-9_.-]{0,99}$")



def is_team_document(data: Any) -> bool:
    """Whether a decoded TOML document declares ``[[robots]]``."""
    return isinstance(data, dict) and "robots" in data


def _robot_sensor(t: Table, dt: float) -> RobotSensorSpec:
    kind, name, period = sensor_head(t, dt, tuple(ROBOT_MEASUREMENT_DIMS))
    spec = RobotSensorSpec(
        name=name, kind=kind, period=period,
        max_range=t.number("max_range", math.inf, lo=0, hi=1e6, lo_open=True, allow_inf=True),
        fov=t.number("fov", 2 * math.pi, lo=0, hi=2 * math.pi, lo_open=True),
        detection_prob=t.number("detection_prob", 1.0, lo=0, hi=1),
        noise=sensor_noise(t, SensorNoise()),
    )
    t.finish()
    return spec


def _rewrite(message: str, file: str, i: int, sensor_index: list[int]) -> str:
    """A single-robot parser message about robot i's document, with its key paths named as
    in the team file (``robot.x`` -> ``robots[i].x``, ``sensors[k]`` -> ``robots[i].sensors[k']``)."""
    head = f"{file}: "
    if not message.startswith(head):
        return message
    body = message[len(head):]

    def sensor(m: re.Match) -> str:
        k = int(m.group(1))
        return f"robots[{i}].sensors[{sensor_index[k] if k < len(sensor_index) else k}]"

    body = re.sub(r"(?<![\w\].])sensors\[(\d+)\]", sensor, body)
    body = re.sub(r"(?<![\w\].])(robot\.|driver|initial_belief|model)",
                  lambda m: f"robots[{i}]." + (m.group(1)[len("robot."):] if m.group(1) == "robot." else
                                               m.group(1)), body)
    return head + body


def parse_team_scenario(data: dict[str, Any], file: str, name: str = "") -> TeamScenario:
    """Validate a decoded team TOML document and build the :class:`TeamScenario`."""
    if not isinstance(data, dict):
        raise ScenarioError(f"{file}: expected a table at the top level")
    for k in _SINGLE_ONLY:
        if k in data:
            raise ScenarioError(f"{file}: {k}: a team scenario declares it inside each "
                                f"[[robots]] entry, not at the top level")
    raw_robots = data.get("robots")
    if not isinstance(raw_robots, list) or not 1 <= len(raw_robots) <= MAX_ROBOTS \
            or not all(isinstance(r, dict) for r in raw_robots):
        raise ScenarioError(f"{file}: robots: expected an array of 1 to {MAX_ROBOTS} tables "
                            "[[robots]]")
    shared = {k: v for k, v in data.items() if k in _SHARED_KEYS}
    unknown = [k for k in data if k not in _SHARED_KEYS and k != "robots"]
    if unknown:
        raise ScenarioError(f"{file}: unknown key {unknown[0]!r}")
    default_filters = shared.pop("default_filters", list(DEFAULT_TEAM_FILTERS))
    if not isinstance(default_filters, list) or not all(isinstance(f, str) for f in default_filters) \
            or not 1 <= len(default_filters) <= 16:
        raise ScenarioError(f"{file}: default_filters = {default_filters!r}: expected a list of "
                            "1 to 16 team filter names")
    for i, spec in enumerate(default_filters):
        if not _DATA_TEAM_FILTER.match(spec):  # files are data: a scenario never names code
            raise ScenarioError(
                f"{file}: default_filters[{i}] = {spec!r}: expected a team filter or "
                "independent:NAME with a built-in filter or an installed entry point (a scenario "
                "may not name a file or module; pass --filter on the command line to run one)")
    robots: list[TeamRobot] = []
    names: set[str] = set()
    ids: set[int] = set()
    team_name = str(shared.get("name", name or Path(file).stem))
    for i, rd in enumerate(raw_robots):
        path = f"robots[{i}]"
        bad = [k for k in rd if k not in ROBOT_KEYS]
        if bad:
            raise ScenarioError(f"{file}: unknown key '{path}.{bad[0]}'")
        t = Table(rd, path, file)
        rname = t.string("name", f"robot{i + 1}")
        rid = t.integer("id", i + 1, lo=1, hi=2**31 - 1)
        if rname in names:
            t.fail(t.key("name"), rname, "a name no other robot has")
        if rid in ids:
            t.fail(t.key("id"), rid, "an ID no other robot has")
        names.add(rname)
        ids.add(rid)
        sensors = rd.get("sensors", [])
        if not isinstance(sensors, list) or len(sensors) > MAX_SENSORS \
                or not all(isinstance(s, dict) for s in sensors):
            t.fail(t.key("sensors"), sensors, f"an array of at most {MAX_SENSORS} tables")
        beacon_sensors = [s for s in sensors if not str(s.get("kind", "")).startswith("robot_")]
        sensor_index = [k for k, s in enumerate(sensors) if not str(s.get("kind", "")).startswith("robot_")]
        dt = float(shared.get("dt", 0.1)) if isinstance(shared.get("dt", 0.1), int | float) else 0.1
        robot_sensors = tuple(_robot_sensor(Table(s, f"{path}.sensors[{k}]", file), dt)
                              for k, s in enumerate(sensors) if str(s.get("kind", "")).startswith("robot_"))
        model = dict(rd.get("model", {})) if isinstance(rd.get("model", {}), dict) else rd.get("model")
        model_robot: list[RobotSensorSpec] = []
        if isinstance(model, dict) and isinstance(model.get("sensors"), dict):
            ms = dict(model["sensors"])
            for rs in robot_sensors:
                if rs.name in ms:
                    st = Table(ms.pop(rs.name), f"{path}.model.sensors.{rs.name}", file)
                    model_robot.append(replace(rs, noise=sensor_noise(st, rs.noise)))
                    st.finish()
                else:
                    model_robot.append(rs)
            model["sensors"] = ms
        else:
            model_robot = list(robot_sensors)
        doc = dict(shared)
        doc["robot"] = {k: rd[k] for k in ("initial_pose", "radius", "motion_noise") if k in rd}
        doc["sensors"] = beacon_sensors
        for k in ("driver", "initial_belief"):
            if k in rd:
                doc[k] = rd[k]
        if model is not None and "model" in rd:
            doc["model"] = model
        doc["name"] = f"{team_name}/{rname}"
        try:
            sc = parse_scenario(doc, file)
        except ScenarioError as exc:
            raise ScenarioError(_rewrite(str(exc), file, i, sensor_index)) from None
        robots.append(TeamRobot(rname, rid, sc, robot_sensors, tuple(model_robot)))
    first = robots[0].scenario
    return TeamScenario(
        name=team_name, description=first.description, source=file, dt=first.dt,
        duration=first.duration, seed=first.seed, world=first.world, keyboard=first.keyboard,
        robots=tuple(robots), default_filters=tuple(default_filters),
        filter_params=dict(first.filter_params))



def parse_any_scenario(data: Any, file: str, name: str = "") -> TeamScenario:
    """Any decoded scenario document as a team: a ``[[robots]]`` document parsed by
    :func:`parse_team_scenario`, a single-robot one by ``parse_scenario`` and made a team of
    one (:func:`~beacon_sim.core.scenario.team.team_of_one`). ScenarioError: one line."""
    if is_team_document(data):
        return parse_team_scenario(data, file, name=name)
    return team_of_one(parse_scenario(data, file))


def load_any_scenario(name_or_path: str | Path) -> TeamScenario:
    """Any scenario by shipped name or path, as a team (:func:`parse_any_scenario`): a
    ``[[robots]]`` file as its team, a single-robot file as a team of one. ScenarioError:
    one line."""
    if is_team_scenario(name_or_path):
        return load_team_scenario(name_or_path)
    return team_of_one(load_scenario(name_or_path))


def resolve_team_path(name_or_path: str | Path) -> Path:
    """A shipped team scenario's name (``team_sparse``, in ``scenarios/team/``) or a path."""
    shipped = scenario_dir() / "team" / f"{name_or_path}.toml"
    if shipped.is_file():
        return shipped
    return resolve_scenario_path(name_or_path)


def shipped_team_scenarios() -> list[str]:
    """Names of the shipped team scenarios (``scenarios/team/*.toml``), sorted."""
    return sorted(p.stem for p in (scenario_dir() / "team").glob("*.toml"))


def is_team_scenario(name_or_path: str | Path) -> bool:
    """Whether a scenario name or path is a team scenario (a shipped team name, or a file
    that declares ``[[robots]]``). False for anything unreadable: loading it as a
    single-robot scenario then gives the usual one-line error."""
    try:
        path = resolve_team_path(name_or_path)
        data = read_toml(path)
    except Exception:
        return False
    return is_team_document(data)


def load_team_scenario(name_or_path: str | Path) -> TeamScenario:
    """Load and validate a team scenario by shipped name or file path (ScenarioError: one line)."""
    path = resolve_team_path(name_or_path)
    data = read_toml(path)
    if not is_team_document(data):
        raise ScenarioError(f"{path}: not a team scenario (no [[robots]]); use load_scenario")
    return parse_team_scenario(data, str(path), name=path.stem)
