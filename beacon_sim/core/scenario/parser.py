"""A scenario's TOML document parsed into a :class:`~beacon_sim.core.scenario.model.Scenario`
(``parse_scenario``), and a shipped scenario's name or a file's path found and loaded
(``resolve_scenario_path``, ``load_scenario``). Keys, units and defaults: docs/scenarios.md."""

from __future__ import annotations

import difflib
import math
import re
from dataclasses import replace
from pathlib import Path
from typing import Any, Final

from beacon_sim.core.beam_model import RangeModelParams
from beacon_sim.core.drivers import (
    CircleSpec,
    ConstantSpec,
    DriverSpec,
    KeyboardSpec,
    RandomGoalSpec,
    WaypointsSpec,
)
from beacon_sim.core.events import Blackout, Event, Kidnap, NoiseBurst, active_ticks
from beacon_sim.core.files import check_user_file
from beacon_sim.core.keyboard_drive import KeyboardLimits
from beacon_sim.core.motion import MotionNoise
from beacon_sim.core.occupancy import MapError, OccupancyGrid, from_walls, load_map
from beacon_sim.core.scenario.keys import RANGE_MODEL_KEYS
from beacon_sim.core.scenario.limits import (
    MAX_BEACONS,
    MAX_BEAMS,
    MAX_CLUTTER_RATE,
    MAX_COORD,
    MAX_DT,
    MAX_EVENT_TICKS,
    MAX_EVENTS,
    MAX_FRAC,
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
from beacon_sim.core.scenario.model import InitialBelief, Scenario, ScenarioError
from beacon_sim.core.scenario.table import Table, Vec4, finite_in
from beacon_sim.core.scenario.toml_files import (
    env_limit,
    read_toml,
)
from beacon_sim.core.sensor_kinds import kind_names, sensor_kind
from beacon_sim.core.sensors import SensorNoise, SensorSpec
from beacon_sim.core.types import Beacon
from beacon_sim.core.world import World

#: A filter a scenario may name: a built-in or an entry point (``ekf``), with an optional
#: label (``mine=ekf``); never a ``file.py:Class`` or ``pkg.mod:Class`` (code to import).
_DATA_FILTER: Final = re.compile(
    r"^(?:[A-Za-z0-9_][A-Za-z0-9_.'+-]{0,63}=)?[A-Za-z0-9_][A-Za-z0-9_.-]{0,99}$")


def _motion_noise(t: Table, base: MotionNoise | None = None) -> MotionNoise:
    b = base or MotionNoise()
    out = MotionNoise(
        v_std=t.number("v_std", b.v_std, lo=0, hi=MAX_SPEED),
        v_frac=t.number("v_frac", b.v_frac, lo=0, hi=MAX_FRAC),
        omega_std=t.number("omega_std", b.omega_std, lo=0, hi=MAX_TURN),
        omega_frac=t.number("omega_frac", b.omega_frac, lo=0, hi=MAX_FRAC),
        pose_std=t.vector3("pose_std", b.pose_std, lo=0, hi=MAX_SPEED),
    )
    t.finish()
    return out


def sensor_noise(t: Table, base: SensorNoise) -> SensorNoise:
    return SensorNoise(
        bearing_std=t.number("bearing_std", base.bearing_std, lo=MIN_SENSOR_STD, hi=MAX_STD),
        range_std=t.number("range_std", base.range_std, lo=MIN_SENSOR_STD, hi=MAX_STD),
        position_std=t.number("position_std", base.position_std, lo=MIN_SENSOR_STD, hi=MAX_STD),
        heading_std=t.number("heading_std", base.heading_std, lo=MIN_SENSOR_STD, hi=MAX_STD),
    )


def sensor_head(t: Table, dt: float, kinds: tuple[str, ...]) -> tuple[str, str, float]:
    """A sensor table's ``kind`` (one of ``kinds``), ``name`` (default: the kind) and
    ``period`` [s] (default ``dt``; a whole multiple of ``dt``), checked."""
    kind = t.string("kind", choices=kinds)
    name = t.string("name", kind)
    period = t.number("period", dt, lo=0, hi=MAX_TICKS * dt, lo_open=True)
    ratio = period / dt
    if abs(ratio - round(ratio)) > 1e-6 or round(ratio) < 1:
        t.fail(t.key("period"), period, f"a whole multiple of dt = {dt:g} s")
    return kind, name, period


def _sensor(t: Table, dt: float) -> SensorSpec:
    kind, name, period = sensor_head(t, dt, kind_names())
    spec = SensorSpec(
        name=name,
        kind=kind,
        period=period,
        max_range=t.number("max_range", math.inf, lo=0, hi=MAX_COORD, lo_open=True, allow_inf=True),
        fov=t.number("fov", 2 * math.pi, lo=0, hi=2 * math.pi, lo_open=True),
        detection_prob=t.number("detection_prob", 1.0, lo=0, hi=1),
        outlier_rate=t.number("outlier_rate", 0.0, lo=0, hi=1),
        min_beacons=t.integer("min_beacons", 2 if kind == "position" else 1, lo=1, hi=MAX_BEACONS),
        beacon_height=t.number("beacon_height", 0.0, lo=0, hi=MAX_COORD),
        noise=sensor_noise(t, SensorNoise()),
        occluded_by_walls=t.boolean("occluded_by_walls", True),  # walls hide beacons
        **_correspondence(t, kind),
    )
    if kind == "position" and spec.min_beacons < 2:
        t.fail(t.key("min_beacons"), spec.min_beacons, "at least 2 for a position fix")
    if spec.clutter_rate > 0 and kind == "range_bearing" and not math.isfinite(spec.max_range):
        t.fail(t.key("max_range"), spec.max_range, "a finite range when clutter_rate > 0 (clutter "
                                                   "ranges are uniform in [0, max_range])")
    if sensor_kind(kind).scan:
        if not math.isfinite(spec.max_range):
            t.fail(t.key("max_range"), t.raw("max_range", "inf"),
                   f"a finite maximum range [m] for a {kind} (its no-return reading)")
        d = RangeModelParams()
        model = {k: t.number(k, getattr(d, k), lo=0, hi=MAX_STD,
                             lo_open=k in ("sigma_hit", "lambda_short")) for k in RANGE_MODEL_KEYS}
        if sum(model[k] for k in ("z_hit", "z_short", "z_max", "z_rand")) <= 0:
            t.fail(t.key("z_hit"), model["z_hit"], "weights z_hit + z_short + z_max + z_rand > 0")
        spec = replace(spec, n_beams=t.integer("n_beams", 180, lo=1, hi=MAX_BEAMS),
                       range_model=RangeModelParams(**model, laser_max_range=spec.max_range))
    own = sensor_kind(kind).params
    if own:
        spec = replace(spec, params=tuple((p.key, t.number(p.key, p.default, lo=p.lo, hi=p.hi))
                                          for p in own))
    t.finish()
    return spec


def _correspondence(t: Table, kind: str) -> dict[str, Any]:
    """The keys ``correspondence`` ("known" | "unknown", beacon sensors only) and
    ``clutter_rate`` (false detections per reading, unknown correspondence only)."""
    corr = t.string("correspondence", "known", choices=("known", "unknown"))
    if corr == "unknown" and kind not in ("bearing", "range_bearing"):
        t.fail(t.key("correspondence"), corr, f"'known' for a {kind} fix (only bearing and "
                                              "range_bearing readings can hide their beacon)")
    rate = t.number("clutter_rate", 0.0, lo=0, hi=MAX_CLUTTER_RATE)
    if rate > 0 and corr != "unknown":
        t.fail(t.key("clutter_rate"), rate, "0 unless correspondence = 'unknown' (a false "
                                            "detection has no beacon ID to carry)")
    return {"correspondence": corr, "clutter_rate": rate}


def _driver(t: Table, world: World) -> DriverSpec:
    kind = t.string("kind", "keyboard",
                    choices=("keyboard", "constant", "circle", "random_goal", "waypoints"))
    spec: DriverSpec
    if kind == "constant":
        spec = ConstantSpec(v=t.number("v", 0.0, lo=-MAX_SPEED, hi=MAX_SPEED),
                            omega=t.number("omega", 0.0, lo=-MAX_TURN, hi=MAX_TURN))
    elif kind == "circle":
        spec = CircleSpec(radius=t.number("radius", 1.0, lo=1e-3, hi=MAX_COORD),
                          speed=t.number("speed", 0.2, lo=-MAX_SPEED, hi=MAX_SPEED))
    elif kind == "random_goal":
        d = RandomGoalSpec()
        spec = RandomGoalSpec(
            speed=t.number("speed", d.speed, lo=0, hi=MAX_SPEED, lo_open=True),
            gain=t.number("gain", d.gain, lo=0, hi=1e3, lo_open=True),
            max_omega=t.number("max_omega", d.max_omega, lo=0, hi=MAX_TURN, lo_open=True),
            tolerance=t.number("tolerance", d.tolerance, lo=0, hi=MAX_COORD, lo_open=True),
            margin=t.number("margin", d.margin, lo=0, hi=0.5 * min(world.width, world.height),
                            what=f"in [0, {0.5 * min(world.width, world.height):g}) (half the "
                                 "room's smaller side)"),
        )
        if spec.margin >= 0.5 * min(world.width, world.height):
            t.fail(t.key("margin"), spec.margin, "less than half the room's smaller side")
    elif kind == "waypoints":
        dw = WaypointsSpec()
        pts = t.raw("points")
        ok = isinstance(pts, list) and 1 <= len(pts) <= MAX_EVENTS and all(
            isinstance(p, list) and len(p) == 2
            and all(isinstance(v, int | float) and not isinstance(v, bool)
                    and finite_in(v, -MAX_COORD, MAX_COORD) for v in p)
            for p in pts)
        if not ok:
            t.fail(t.key("points"), pts if len(str(pts)) < 200 else f"{str(pts)[:80]}...",
                   f"a list of 1 to {MAX_EVENTS} [x, y] pairs of finite numbers in metres")
        spec = WaypointsSpec(
            points=tuple((float(p[0]), float(p[1])) for p in pts),
            speed=t.number("speed", dw.speed, lo=0, hi=MAX_SPEED, lo_open=True),
            gain=t.number("gain", dw.gain, lo=0, hi=1e3, lo_open=True),
            max_omega=t.number("max_omega", dw.max_omega, lo=0, hi=MAX_TURN, lo_open=True),
            tolerance=t.number("tolerance", dw.tolerance, lo=0, hi=MAX_COORD, lo_open=True),
            loop=t.boolean("loop", True),
        )
    else:
        spec = KeyboardSpec()
    t.finish()
    return spec


def _event(t: Table, sensor_names: set[str], dt: float) -> Event:
    kind = t.string("kind", choices=("kidnap", "blackout", "noise_burst"))
    latest = MAX_TICKS * dt
    time = t.number("time", lo=0, hi=latest)
    ev: Event
    if kind == "kidnap":
        given = [k for k in ("pose", "offset", "random") if t.has(k)]
        if len(given) != 1:
            t.fail(t.path, {k: t.data[k] for k in given},
                   "exactly one of pose = [x, y, theta], offset = [dx, dy, dtheta], "
                   "random = true")
        ev = Kidnap(
            time=time,
            pose=t.vector3("pose", None),
            offset=t.vector3("offset", None),
            random=t.boolean("random", False),
        )
        if given == ["random"] and not ev.random:
            t.fail(t.key("random"), False, "true (or give pose or offset instead)")
    elif kind == "blackout":
        sensors = t.raw("sensors", [])
        if not isinstance(sensors, list) or len(sensors) > MAX_SENSORS \
                or any(not isinstance(s, str) or s not in sensor_names for s in sensors):
            t.fail(t.key("sensors"), sensors,
                   "a list of sensor names from: " + ", ".join(sorted(sensor_names)))
        ev = Blackout(time=time, duration=t.number("duration", lo=0, hi=latest, lo_open=True),
                      sensors=tuple(sensors))
    else:
        ev = NoiseBurst(time=time, duration=t.number("duration", lo=0, hi=latest, lo_open=True),
                        v_std=t.number("v_std", 0.0, lo=0, hi=MAX_SPEED),
                        omega_std=t.number("omega_std", 0.0, lo=0, hi=MAX_TURN))
    t.finish()
    return ev


def _walls(w: Table, file: str, base_dir: Path,
           map_grid: OccupancyGrid | None = None) -> OccupancyGrid | None:
    """The map a ``world.map`` key names (a ROS map_server YAML, relative to the scenario
    file; ``map_grid`` instead when given: a recording's stored map), or None;
    ``world.walls`` is read later, once the bounds are known."""
    if w.has("map") and w.has("walls"):
        raise ScenarioError(f"{file}: world.map and world.walls: expected one of them, not both")
    if not w.has("map"):
        return None
    name = w.string("map")
    if map_grid is not None:
        return map_grid
    path = Path(name) if Path(name).is_absolute() else base_dir / name
    try:
        return load_map(path)
    except MapError as exc:
        raise ScenarioError(f"{file}: world.map = {name!r}: {exc}") from None


def _grid_bounds(grid: OccupancyGrid) -> Vec4:
    """The axis-aligned bounds [m] of a grid's corners (the world a map file covers)."""
    rows, cols = grid.shape
    corners = grid.grid_to_world([[0, 0], [cols, 0], [0, rows], [cols, rows]])
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    return (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))


def _walls_grid(w: Table, bounds: Vec4) -> OccupancyGrid:
    """The ``[world.walls]`` table rasterised over ``bounds``: polylines in ``segments`` and
    solid outlines in ``polygons``, each a list of [x, y] points [m]."""
    t = w.sub("walls")
    res = t.number("resolution", 0.05, lo=1e-3, hi=MAX_COORD)
    lines = {}
    total = 0
    for key in ("segments", "polygons"):
        value = t.raw(key, [])
        ok = isinstance(value, list) and all(
            isinstance(line, list) and len(line) >= 2 and all(
                isinstance(p, list) and len(p) == 2 and all(
                    isinstance(v, int | float) and not isinstance(v, bool)
                    and finite_in(v, -MAX_COORD, MAX_COORD) for v in p) for p in line)
            for line in value)
        if ok:
            total += sum(len(line) for line in value)
        if not ok or total > MAX_WALL_POINTS:
            shown = value if len(str(value)) < 120 else f"{str(value)[:80]}..."
            t.fail(t.key(key), shown, f"a list of polylines, each a list of at least two [x, y] "
                                      f"points [m] (at most {MAX_WALL_POINTS:,} points in all)")
        lines[key] = [[(float(p[0]), float(p[1])) for p in line] for line in value]
    t.finish()
    try:
        return from_walls(bounds, res, segments=lines["segments"], polygons=lines["polygons"])
    except MapError as exc:
        raise ScenarioError(f"{t.file}: {t.path}: {exc}") from None


def parse_scenario(data: dict[str, Any], file: str, name: str = "", *,
                   base_dir: str | Path | None = None,
                   map_grid: OccupancyGrid | None = None) -> Scenario:
    """Validate a decoded TOML document and build the :class:`Scenario`. A ``world.map`` path
    is relative to ``base_dir`` (default: the folder of ``file``); ``map_grid``, when given,
    is that map instead of the file (a recording's stored map)."""
    top = Table(data, "", file)
    name = top.string("name", name or Path(file).stem)
    description = top.string("description", "")
    dt = top.number("dt", 0.1, lo=MIN_DT, hi=MAX_DT)
    duration = top.number("duration", 60.0, lo=0, hi=MAX_TICKS * dt, lo_open=True,
                          what=f"in (0, {MAX_TICKS * dt:g}] (at most {MAX_TICKS:,} ticks of dt)")
    if round(duration / dt) < 1:
        top.fail("duration", duration, f"at least one tick of dt = {dt:g} s")
    seed = top.integer("seed", 0, lo=0, hi=2**63 - 1)

    w = top.sub("world")
    grid = _walls(w, file, Path(file).parent if base_dir is None else Path(base_dir), map_grid)
    if grid is not None and not w.has("bounds"):
        bounds = _grid_bounds(grid)
    else:
        bounds = w.vector4("bounds")
    if not (bounds[2] - bounds[0] >= MIN_WORLD_SIDE and bounds[3] - bounds[1] >= MIN_WORLD_SIDE):
        w.fail(w.key("bounds"), list(bounds), f"[xmin, ymin, xmax, ymax] with xmax - xmin and "
                                              f"ymax - ymin at least {MIN_WORLD_SIDE:g} m")
    beacons: list[Beacon] = []
    raw_beacons = w.raw("beacons", [])
    if isinstance(raw_beacons, list) and len(raw_beacons) > MAX_BEACONS:
        w.fail(w.key("beacons"), f"[... {len(raw_beacons):,} beacons]", f"at most {MAX_BEACONS:,} beacons")
    ids: set[int] = set()
    anchors: list[tuple[int, str]] = []  # (beacon ID, key path) of each anchor = true
    for bt in w.tables("beacons"):
        b = Beacon(id=bt.integer("id", lo=0, hi=2**31 - 1),
                   x=bt.number("x", lo=-MAX_COORD, hi=MAX_COORD),
                   y=bt.number("y", lo=-MAX_COORD, hi=MAX_COORD))
        if b.id in ids:
            bt.fail(bt.key("id"), b.id, "an ID no other beacon has")
        ids.add(b.id)
        if bt.boolean("anchor", False):
            anchors.append((b.id, bt.key("anchor")))
        bt.finish()
        beacons.append(b)
    if w.has("walls"):
        grid = _walls_grid(w, bounds)
    w.finish()
    world = World(bounds=bounds, beacons=tuple(beacons), grid=grid)

    r = top.sub("robot")
    initial_pose = r.vector3("initial_pose")
    if not world.contains(initial_pose[:2]):
        r.fail(r.key("initial_pose"), list(initial_pose), f"a position inside world.bounds {list(bounds)}")
    radius = r.number("radius", 0.2, lo=0, hi=MAX_COORD, lo_open=True)
    if not world.is_free(initial_pose, radius):
        r.fail(r.key("initial_pose"), list(initial_pose),
               f"a position at least robot.radius = {radius:g} m from every wall")
    motion_noise = _motion_noise(r.sub("motion_noise", {}))
    r.finish()

    sensor_tables = top.tables("sensors")
    if len(sensor_tables) > MAX_SENSORS:
        top.fail("sensors", f"[... {len(sensor_tables)} sensors]", f"at most {MAX_SENSORS} sensors")
    sensors = tuple(_sensor(st, dt) for st in sensor_tables)
    names = [s.name for s in sensors]
    for i, n in enumerate(names):
        if n in names[:i]:
            raise ScenarioError(f"{file}: sensors[{i}].name = {n!r}: expected a unique name")
    if any(sensor_kind(s.kind).needs_beacons for s in sensors) and not beacons:
        raise ScenarioError(f"{file}: world.beacons = []: expected at least one beacon for the sensors")
    for i, s in enumerate(sensors):
        check = sensor_kind(s.kind).check
        why = None if check is None else check(s, world, f"sensors[{i}]")
        if why:
            raise ScenarioError(f"{file}: {why}")
        if sensor_kind(s.kind).needs_walls and grid is None:
            raise ScenarioError(f"{file}: world: a {s.kind} sensor needs walls: expected "
                                f"world.map = \"file.yaml\" or a [world.walls] table")

    driver = _driver(top.sub("driver", {}), world)
    k = top.sub("keyboard", {})
    kd = KeyboardLimits()
    keyboard = KeyboardLimits(
        v_step=k.number("v_step", kd.v_step, lo=0, hi=MAX_SPEED, lo_open=True),
        v_max=k.number("v_max", kd.v_max, lo=0, hi=MAX_SPEED, lo_open=True),
        v_min=k.number("v_min", kd.v_min, lo=-MAX_SPEED, hi=0),
        omega_step=k.number("omega_step", kd.omega_step, lo=0, hi=MAX_TURN, lo_open=True),
        omega_max=k.number("omega_max", kd.omega_max, lo=0, hi=MAX_TURN, lo_open=True),
    )
    k.finish()

    event_tables = top.tables("events")
    if len(event_tables) > MAX_EVENTS:
        top.fail("events", f"[... {len(event_tables):,} events]", f"at most {MAX_EVENTS:,} events")
    events = tuple(_event(et, set(names), dt) for et in event_tables)
    covered = sum(len(active_ticks(ev, dt)) for ev in events if not isinstance(ev, Kidnap))
    if covered > MAX_EVENT_TICKS:
        raise ScenarioError(f"{file}: events: blackouts and noise bursts cover {covered:,} ticks "
                            f"together: expected at most {MAX_EVENT_TICKS:,}")

    ib = top.sub("initial_belief", {})
    initial_belief = InitialBelief(
        mean=ib.vector3("mean", initial_pose),
        std=ib.vector3("std", (0.1, 0.1, 0.05), lo=0, hi=MAX_COORD),
        global_=ib.boolean("global", False),
    )
    ib.finish()

    m = top.sub("model", {})
    map_known = m.string("map", "known", choices=("known", "unknown")) == "known"
    if not map_known and len(beacons) > MAX_SLAM_BEACONS:
        m.fail(m.key("map"), "unknown", f"a map the filters build of at most {MAX_SLAM_BEACONS:,} "
               f"beacons (the world has {len(beacons):,}: a SLAM filter's work grows with each)")
    if map_known and anchors:
        raise ScenarioError(f"{file}: {anchors[0][1]} = true: an anchor only means something when "
                            f"the filters are not given the map; add model.map = \"unknown\" (SLAM) "
                            f"or remove the key")
    model_motion = _motion_noise(m.sub("motion_noise", {}), base=motion_noise)
    ms = m.sub("sensors", {})
    model_sensors = []
    for s in sensors:
        if ms.has(s.name):
            st = ms.sub(s.name)
            own = sensor_kind(s.kind).params   # the filters may be told other kind keys too
            told = tuple((p.key, st.number(p.key, s.param(p.key), lo=p.lo, hi=p.hi)) for p in own)
            model_sensors.append(replace(s, noise=sensor_noise(st, s.noise), params=told))
            st.finish()
        else:
            model_sensors.append(s)
    unknown = [n for n in ms.data if n not in names]
    if unknown:
        hint = difflib.get_close_matches(unknown[0], names, n=1)
        extra = f" (did you mean {hint[0]!r}?)" if hint else ""
        raise ScenarioError(
            f"{file}: model.sensors.{unknown[0]}: no sensor of that name{extra}")
    ms.used.update(names)
    ms.finish()
    m.finish()

    default_filters = top.raw("default_filters", ["ekf", "dead_reckoning"])
    if not isinstance(default_filters, list) or not all(isinstance(f, str) for f in default_filters) \
            or len(default_filters) > MAX_SENSORS:
        top.fail("default_filters", default_filters, "a list of filter names")
    for i, spec in enumerate(default_filters):
        if not _DATA_FILTER.match(spec):  # files are data: a scenario never names code to run
            top.fail(f"default_filters[{i}]", spec,
                     "a built-in filter or an installed entry point (a scenario may not name a "
                     "file or module; pass --filter on the command line to run one)")
    fp = top.raw("filters", {})
    if not isinstance(fp, dict) or not all(isinstance(v, dict) for v in fp.values()):
        top.fail("filters", fp, "tables [filters.NAME] of filter parameters")
    top.finish()

    return Scenario(
        name=name, description=description, source=file, dt=dt, duration=duration, seed=seed,
        world=world, initial_pose=initial_pose, robot_radius=radius, motion_noise=motion_noise,
        sensors=sensors, driver=driver, keyboard=keyboard, events=events,
        initial_belief=initial_belief, model_motion_noise=model_motion,
        model_sensors=tuple(model_sensors), default_filters=tuple(default_filters),
        filter_params={k: dict(v) for k, v in fp.items()},
        map_known=map_known, anchor_ids=tuple(i for i, _ in anchors),
    )


def resolve_scenario_path(name_or_path: str | Path) -> Path:
    """A shipped scenario's name (``default``) or a path to a ``.toml`` file."""
    from beacon_sim.core.resources import scenario_dir, shipped_scenarios

    p = Path(name_or_path)
    if p.suffix == ".toml" or p.exists() or "/" in str(name_or_path):
        if not p.exists():
            raise ScenarioError(f"{p}: no such scenario file")
        check_user_file(p, what="scenario file", cap=env_limit("SCENARIO_BYTES", MAX_SCENARIO_BYTES),
                        error=ScenarioError, hint=" (BEACON_SIM_MAX_SCENARIO_BYTES raises the cap)")
        return p
    shipped = scenario_dir() / f"{name_or_path}.toml"
    if not shipped.is_file():
        names = shipped_scenarios()
        hint = difflib.get_close_matches(str(name_or_path), names, n=1)
        extra = f" (did you mean {hint[0]!r}?)" if hint else ""
        raise ScenarioError(
            f"{name_or_path}: no shipped scenario of that name{extra}; "
            f"choose one of {', '.join(names)} or give a path to a .toml file")
    return shipped


def load_scenario(name_or_path: str | Path) -> Scenario:
    """Load and validate a scenario by shipped name or file path.

    Raises
    ------
    ScenarioError
        With a one-line message naming the file, key, value and what was expected.
    """
    path = resolve_scenario_path(name_or_path)
    return parse_scenario(read_toml(path), str(path), name=path.stem)


__all__ = ["load_scenario", "parse_scenario", "resolve_scenario_path", "sensor_noise"]
