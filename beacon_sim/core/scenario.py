"""Scenario files (TOML) parsed into frozen dataclasses and validated at load.

Every error names the file, the key path, the bad value and what was expected; unknown
keys are errors with a "did you mean". The keys, units and defaults are documented in
docs/scenarios.md.
"""

from __future__ import annotations

import difflib
import enum
import hashlib
import math
import os
import re
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Final, NoReturn, overload

from beacon_sim.core import arguments
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
from beacon_sim.core.files import check_user_file, read_user_text
from beacon_sim.core.keyboard_drive import KeyboardLimits
from beacon_sim.core.motion import MotionNoise
from beacon_sim.core.occupancy import MapError, OccupancyGrid, from_walls, load_map
from beacon_sim.core.sensor_kinds import kind_names, param_keys, sensor_kind
from beacon_sim.core.sensors import SensorNoise, SensorSpec
from beacon_sim.core.types import Beacon
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
class Scenario:
    """A complete, validated scenario. See docs/scenarios.md for every key."""

    name: str
    description: str
    source: str
    dt: float
    duration: float
    seed: int
    world: World
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


class _Required(enum.Enum):
    """The type of ``_REQUIRED``: a key with no default must be in the file."""

    TOKEN = 0


_REQUIRED: Final = _Required.TOKEN

# Physical ranges (docs/scenarios.md, "Ranges"): every number in a scenario is finite and
# within these, so that nothing overflows, hangs or fills the memory.
#: Largest coordinate, length or angle in a vector [m or rad].
MAX_COORD: Final = 1e6
#: Smallest and largest tick [s].
MIN_DT: Final = 1e-3
MAX_DT: Final = 10.0
#: Most ticks in a run (duration / dt), and latest event time in ticks.
MAX_TICKS: Final = 1_000_000
#: Largest speed [m/s], turn rate [rad/s] and their noise.
MAX_SPEED: Final = 100.0
MAX_TURN: Final = 100.0
#: Largest sensor noise standard deviation [m or rad] and fraction of the command.
MAX_STD: Final = 1e3
MAX_FRAC: Final = 10.0
#: Most beacons, sensors and events in a scenario, and most ticks covered by all the
#: blackouts and noise bursts together (their per-tick tables must fit in memory).
MAX_BEACONS: Final = 10_000
#: Most beacons with ``model.map = "unknown"`` (SLAM: the filters' state grows with the map).
MAX_SLAM_BEACONS: Final = 500
MAX_SENSORS: Final = 100
MAX_EVENTS: Final = 10_000
MAX_EVENT_TICKS: Final = 2_000_000
#: Smallest sensor noise standard deviation [m or rad]: a filter divides by its square
#: (zero, or a subnormal, would divide by zero or overflow in the bound and the filters).
MIN_SENSOR_STD: Final = 1e-6
#: Shortest side of the world [m] (the window draws a grid of it, the drivers pick goals in it).
MIN_WORLD_SIDE: Final = 0.1

# Caps on the input itself, checked before parsing (docs/scenarios.md, "Caps"); each can be
# raised with the environment variable ``BEACON_SIM_MAX_<NAME>`` (a whole number).
#: Largest scenario file [bytes] (10,000 beacons and 10,000 events take under 1 MiB; a
#: file of this size parses in about a second).
MAX_SCENARIO_BYTES: Final = 2 * 2**20
#: Deepest nesting of arrays and tables in a scenario or a recording line (the shipped
#: files nest at most 5 deep).
MAX_NESTING: Final = 32
#: Most decimal digits of an integer in a scenario or a recording (2^63 has 19).
MAX_INT_DIGITS: Final = 20


def env_limit(name: str, default: int) -> int:
    """A cap: ``default``, or the whole number in the environment variable
    ``BEACON_SIM_MAX_<name>`` (to raise it)."""
    var = f"BEACON_SIM_MAX_{name}"
    raw = os.environ.get(var)
    if raw is None:
        return default
    try:
        value = int(raw.replace("_", ""))
    except ValueError:
        value = 0
    if value < 1:
        raise ScenarioError(f"{var}={raw[:40]!r}: expected a positive whole number (a cap; "
                            f"the default is {default:,})")
    return value


def document_shape(obj: Any, limit: int) -> tuple[int, int]:
    """(how deep arrays and tables nest in ``obj``, counted up to ``limit + 1``; the largest
    absolute integer in it), so that a hostile document costs no more than the cap."""
    depth, level, biggest = 0, [obj], 0
    while level and depth <= limit:
        nxt: list[Any] = []
        for x in level:
            if isinstance(x, dict):
                nxt.extend(x.values())
            elif isinstance(x, list | tuple):
                nxt.extend(x)
            elif type(x) is int and not -biggest <= x <= biggest:
                biggest = abs(x)
        if not nxt:
            break
        depth += 1
        level = nxt
    return depth, biggest


def check_document(data: Any, file: str) -> None:
    """The caps every decoded scenario (or recording line) obeys: nesting depth
    (``MAX_NESTING``) and integer size (``MAX_INT_DIGITS``); ScenarioError, one line."""
    limit = env_limit("NESTING", MAX_NESTING)
    digits = env_limit("INT_DIGITS", MAX_INT_DIGITS)
    depth, biggest = document_shape(data, limit)
    if depth > limit:
        raise ScenarioError(f"{file}: arrays or tables nested deeper than {limit} levels "
                            f"(BEACON_SIM_MAX_NESTING raises the cap)")
    if biggest >= 10**digits:
        raise ScenarioError(f"{file}: an integer of more than {digits} digits (at most {digits}; "
                            f"BEACON_SIM_MAX_INT_DIGITS raises the cap)")


def parse_toml_text(text: str, file: str) -> dict[str, Any]:
    """A TOML document decoded and checked against the caps (ScenarioError, one line)."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{file}: not valid TOML: {exc}") from None
    except RecursionError:
        raise ScenarioError(f"{file}: arrays or tables nested too deep to read (at most "
                            f"{env_limit('NESTING', MAX_NESTING)} levels)") from None
    except ValueError as exc:  # e.g. an integer over Python's 4,300-digit limit
        raise ScenarioError(f"{file}: not valid TOML: {str(exc).splitlines()[0][:100]}") from None
    check_document(data, file)
    return data


def read_user_toml(path: str | Path, *, what: str, cap: int,
                   error: type[BeaconSimError] = ScenarioError, hint: str = "") -> dict[str, Any]:
    """A user's TOML file other than a scenario (a grade config): a regular file within
    ``cap`` bytes (:func:`~beacon_sim.core.files.read_user_text`), decoded and checked
    against the same caps on nesting and integers as a scenario; ``error``, one line."""
    text = read_user_text(path, what=what, cap=cap, error=error, hint=hint)
    try:
        return parse_toml_text(text, str(path))
    except ScenarioError as exc:
        raise error(str(exc)) from None


#: The last document read (key: path and the SHA-256 of its text), so that telling a team
#: file from a single-robot one and then loading it parses the file once.
_last_read: list[Any] = [None, None]


def read_toml(path: Path) -> dict[str, Any]:
    """A scenario file's TOML document: its size checked first (``MAX_SCENARIO_BYTES``),
    then decoded and checked (ScenarioError, one line). Callers do not modify it."""
    text = read_user_text(path, what="scenario file", cap=env_limit("SCENARIO_BYTES", MAX_SCENARIO_BYTES),
                          error=ScenarioError, hint=" (BEACON_SIM_MAX_SCENARIO_BYTES raises the cap)")
    key = (str(path), hashlib.sha256(text.encode("utf-8")).digest())
    if _last_read[0] == key:
        return _last_read[1]
    data = parse_toml_text(text, str(path))
    _last_read[:] = [key, data]
    return data

Vec3 = tuple[float, float, float]
Vec4 = tuple[float, float, float, float]


class _Table:
    """Reads one TOML table, tracking the key path for error messages."""

    def __init__(self, data: Any, path: str, file: str):
        self.file = file
        self.path = path
        if not isinstance(data, dict):
            self.fail(path or "<top level>", data, "a table")
        self.data = data
        self.used: set[str] = set()
        # Unknown keys first: a misspelt table name should not be reported as a missing one.
        known = _known(_generic_path(path))
        if known is not None:
            for k in data:
                if k not in known:
                    hint = difflib.get_close_matches(k, sorted(known), n=1)
                    extra = f" (did you mean {self.key(hint[0])!r}?)" if hint else ""
                    raise ScenarioError(f"{file}: unknown key {self.key(k)!r}{extra}")

    def key(self, name: str) -> str:
        return f"{self.path}.{name}" if self.path else name

    def fail(self, keypath: str, value: Any, expected: str) -> NoReturn:
        raise ScenarioError(f"{self.file}: {keypath} = {value!r}: expected {expected}")

    def has(self, name: str) -> bool:
        return name in self.data

    def raw(self, name: str, default: object = _REQUIRED) -> Any:
        self.used.add(name)
        if name not in self.data:
            if default is _REQUIRED:
                raise ScenarioError(f"{self.file}: missing key {self.key(name)}")
            return default
        return self.data[name]

    def number(self, name: str, default: float | _Required = _REQUIRED, *, lo: float = -math.inf,
               hi: float = math.inf, lo_open: bool = False, what: str | None = None,
               allow_inf: bool = False) -> float:
        """A finite number in ``[lo, hi]`` (``(lo, hi]`` when ``lo_open``); infinity only
        where ``allow_inf`` (e.g. ``max_range = inf``)."""
        value = self.raw(name, default)
        if default is not _REQUIRED and not self.has(name):
            return default
        ok = isinstance(value, int | float) and not isinstance(value, bool)
        if ok:
            try:
                x = float(value)
            except OverflowError:  # an integer too large for a float
                ok = False
        if ok:
            ok = (math.isfinite(x) or (allow_inf and x == math.inf)) \
                and (x > lo if lo_open else x >= lo) and (x <= hi or (allow_inf and x == math.inf))
        if not ok:
            rng = what or _range_text(lo, hi, lo_open)
            self.fail(self.key(name), value, f"a number {rng}" + (" or inf" if allow_inf else ""))
        return float(value)

    def integer(self, name: str, default: int | _Required = _REQUIRED, *, lo: int = -(2**63),
                hi: int = 2**63 - 1) -> int:
        value = self.raw(name, default)
        if default is not _REQUIRED and not self.has(name):
            return default
        if not isinstance(value, int) or isinstance(value, bool) or not lo <= value <= hi:
            self.fail(self.key(name), value, f"an integer {_range_text(lo, hi)}")
        return int(value)

    def boolean(self, name: str, default: bool | _Required = _REQUIRED) -> bool:
        value = self.raw(name, default)
        if not isinstance(value, bool):
            self.fail(self.key(name), value, "true or false")
        return value

    def string(self, name: str, default: str | _Required = _REQUIRED, *,
               choices: Sequence[str] | None = None) -> str:
        value = self.raw(name, default)
        if not isinstance(value, str):
            self.fail(self.key(name), value, "a string")
        if choices is not None and value not in choices:
            hint = difflib.get_close_matches(value, choices, n=1)
            extra = f" (did you mean {hint[0]!r}?)" if hint else ""
            self.fail(self.key(name), value, "one of " + ", ".join(map(repr, choices)) + extra)
        return value

    def _floats(self, name: str, n: int, lo: float, hi: float = 1e6) -> list[float]:
        """The key's list of ``n`` finite numbers, each in ``[lo, hi]`` (the key must be present)."""
        value = self.raw(name)
        ok = isinstance(value, list) and len(value) == n and all(
            isinstance(v, int | float) and not isinstance(v, bool) and _finite_in(v, lo, hi)
            for v in value)
        if not ok:
            self.fail(self.key(name), value, f"a list of {n} finite numbers {_range_text(lo, hi)}")
        return [float(v) for v in value]

    @overload
    def vector3(self, name: str, default: Vec3 | _Required = ..., *, lo: float = ...,
                hi: float = ...) -> Vec3: ...

    @overload
    def vector3(self, name: str, default: None, *, lo: float = ..., hi: float = ...) -> Vec3 | None: ...

    def vector3(self, name: str, default: Vec3 | _Required | None = _REQUIRED, *,
                lo: float = -MAX_COORD, hi: float = MAX_COORD) -> Vec3 | None:
        """A list of 3 finite numbers in ``[lo, hi]``, e.g. a pose ``[x, y, theta]``."""
        if default is not _REQUIRED and not self.has(name):
            self.used.add(name)  # as raw() does
            return default
        x, y, z = self._floats(name, 3, lo, hi)
        return (x, y, z)

    def vector4(self, name: str, *, lo: float = -MAX_COORD, hi: float = MAX_COORD) -> Vec4:
        """A list of 4 finite numbers (required), e.g. bounds ``[xmin, ymin, xmax, ymax]``."""
        a, b, c, d = self._floats(name, 4, lo, hi)
        return (a, b, c, d)

    def sub(self, name: str, default: dict[str, Any] | _Required = _REQUIRED) -> _Table:
        value = self.raw(name, {} if default is not _REQUIRED else _REQUIRED)
        return _Table(value, self.key(name), self.file)

    def tables(self, name: str) -> list[_Table]:
        value = self.raw(name, [])
        if not isinstance(value, list):
            self.fail(self.key(name), value, "an array of tables ([[...]])")
        return [_Table(v, f"{self.key(name)}[{i}]", self.file) for i, v in enumerate(value)]

    def finish(self) -> None:
        unknown = [k for k in self.data if k not in self.used]
        if unknown:
            k = unknown[0]
            hint = difflib.get_close_matches(k, sorted(self.used | _known_keys(self)), n=1)
            extra = f" (did you mean {self.key(hint[0])!r}?)" if hint else ""
            raise ScenarioError(f"{self.file}: unknown key {self.key(k)!r}{extra}")


def _known_keys(table: _Table) -> set[str]:
    return _known(_generic_path(table.path)) or set()


def _known(path: str) -> set[str] | None:
    """The keys a table at ``path`` (``sensors[]``) may have: a sensor's include the keys
    every registered kind declares (core/sensor_kinds.py)."""
    known = _KNOWN.get(path)
    if path == "sensors[]" and known is not None:
        return known | set(param_keys())
    return known


def _generic_path(path: str) -> str:
    return re.sub(r"\[\d+\]", "[]", path)


#: A filter a scenario may name: a built-in or an entry point (``ekf``), with an optional
#: label (``mine=ekf``); never a ``file.py:Class`` or ``pkg.mod:Class`` (code to import).
_DATA_FILTER: Final = re.compile(
    r"^(?:[A-Za-z0-9_][A-Za-z0-9_.'+-]{0,63}=)?[A-Za-z0-9_][A-Za-z0-9_.-]{0,99}$")


def _finite_in(v: float, lo: float, hi: float) -> bool:
    """Whether the number ``v`` (int or float) is finite and in ``[lo, hi]``."""
    try:
        x = float(v)
    except OverflowError:
        return False
    return math.isfinite(x) and lo <= x <= hi


def _range_text(lo: float, hi: float, lo_open: bool = False) -> str:
    if lo > -math.inf and hi < math.inf:
        return f"in {'(' if lo_open else '['}{lo:g}, {hi:g}]"
    if lo > -math.inf:
        return f"{'>' if lo_open else '>='} {lo:g}"
    if hi < math.inf:
        return f"<= {hi:g}"
    return ""


# Every key each table may hold, so that an unknown key gets a "did you mean" even when
# the key it resembles was not written in the file.
_NOISE_KEYS = {"v_std", "v_frac", "omega_std", "omega_frac", "pose_std"}
_SENSOR_NOISE_KEYS = {"bearing_std", "range_std", "position_std", "heading_std"}
#: A laser scan's keys (a kind whose record has ``scan``; docs/maps.md): beams per scan and the
#: truth's beam model.
_RANGE_MODEL_KEYS = ("z_hit", "z_short", "z_max", "z_rand", "sigma_hit", "lambda_short")
_RANGE_FINDER_KEYS = {"n_beams", *_RANGE_MODEL_KEYS}
#: Most beams in one scan.
MAX_BEAMS: Final = 4096
#: Most points in all the walls of a scenario together.
MAX_WALL_POINTS: Final = 100_000
_KNOWN: dict[str, set[str]] = {
    "": {"name", "description", "dt", "duration", "seed", "world", "robot", "sensors",
         "driver", "keyboard", "events", "initial_belief", "model", "default_filters",
         "filters"},
    "world": {"bounds", "beacons", "map", "walls"},
    "world.walls": {"resolution", "segments", "polygons"},
    "world.beacons[]": {"id", "x", "y", "anchor"},
    "robot": {"initial_pose", "radius", "motion_noise"},
    "robot.motion_noise": _NOISE_KEYS,
    "sensors[]": {"name", "kind", "period", "max_range", "fov", "detection_prob",
                  "outlier_rate", "min_beacons", "beacon_height", "correspondence",
                  "clutter_rate", "occluded_by_walls"} | _SENSOR_NOISE_KEYS | _RANGE_FINDER_KEYS,
    "driver": {"kind", "v", "omega", "radius", "speed", "gain", "max_omega", "tolerance",
               "margin", "points", "loop"},
    "keyboard": {"v_step", "v_max", "v_min", "omega_step", "omega_max"},
    "events[]": {"kind", "time", "duration", "pose", "offset", "random", "sensors", "v_std",
                 "omega_std"},
    "initial_belief": {"mean", "std", "global"},
    "model": {"motion_noise", "sensors", "map"},
    "model.motion_noise": _NOISE_KEYS,
}


def _motion_noise(t: _Table, base: MotionNoise | None = None) -> MotionNoise:
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


def _sensor_noise(t: _Table, base: SensorNoise) -> SensorNoise:
    return SensorNoise(
        bearing_std=t.number("bearing_std", base.bearing_std, lo=MIN_SENSOR_STD, hi=MAX_STD),
        range_std=t.number("range_std", base.range_std, lo=MIN_SENSOR_STD, hi=MAX_STD),
        position_std=t.number("position_std", base.position_std, lo=MIN_SENSOR_STD, hi=MAX_STD),
        heading_std=t.number("heading_std", base.heading_std, lo=MIN_SENSOR_STD, hi=MAX_STD),
    )


def _sensor(t: _Table, dt: float) -> SensorSpec:
    kind = t.string("kind", choices=kind_names())
    name = t.string("name", kind)
    period = t.number("period", dt, lo=0, hi=MAX_TICKS * dt, lo_open=True)
    ratio = period / dt
    if abs(ratio - round(ratio)) > 1e-6 or round(ratio) < 1:
        t.fail(t.key("period"), period, f"a whole multiple of dt = {dt:g} s")
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
        noise=_sensor_noise(t, SensorNoise()),
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
                             lo_open=k in ("sigma_hit", "lambda_short")) for k in _RANGE_MODEL_KEYS}
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


#: Most false detections per reading a sensor may declare (clutter).
MAX_CLUTTER_RATE: Final = 5.0


def _correspondence(t: _Table, kind: str) -> dict[str, Any]:
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


def _driver(t: _Table, world: World) -> DriverSpec:
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
                    and _finite_in(v, -MAX_COORD, MAX_COORD) for v in p)
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


def _event(t: _Table, sensor_names: set[str], dt: float) -> Event:
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


def _walls(w: _Table, file: str, base_dir: Path,
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


def _walls_grid(w: _Table, bounds: Vec4) -> OccupancyGrid:
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
                    and _finite_in(v, -MAX_COORD, MAX_COORD) for v in p) for p in line)
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
    top = _Table(data, "", file)
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
            model_sensors.append(replace(s, noise=_sensor_noise(st, s.noise), params=told))
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
