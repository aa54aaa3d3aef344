"""Simulated sensors: which beacons are seen, and the noisy readings they give.

A beacon is seen when it is within ``max_range``, inside the field of view and a Bernoulli
draw with ``detection_prob`` succeeds. With probability ``outlier_rate`` a reading is
replaced by a uniformly random (wrong) one. Each call draws a fixed number of random
numbers, so the sensor stream's state depends only on how many times it was called.

A ``range_finder`` (docs/maps.md) is a laser scan of ``n_beams`` beams over ``fov``,
ray cast on the world's walls from the true pose, each reading drawn from the beam model
(its four parts, ``range_model``) with the sensor's stream.

In a world with walls a beacon behind a wall is not seen (``occluded_by_walls``, on by
default): the segment from the sensor to the beacon must not enter an occupied cell before
the beacon's own (``raycast.line_of_sight``). Without walls nothing is cast and nothing
changes. :func:`visible_mask` is the one home of this visibility: the simulation and the
PCRB (evaluation/pcrb.py) use it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from beacon_sim.core import measurement_models as mm
from beacon_sim.core import portable_math as pm
from beacon_sim.core.angles import wrap
from beacon_sim.core.beam_model import RangeModelParams, sample_beam
from beacon_sim.core.geometry import hdop
from beacon_sim.core.measurement_models import relative_bearing
from beacon_sim.core.raycast import beam_angles, line_of_sight, scan
from beacon_sim.core.types import MEASUREMENT_DIMS, Measurement
from beacon_sim.core.world import World


@dataclass(frozen=True)
class SensorNoise:
    """Noise standard deviations of a sensor (the truth's, or what a filter is told).

    bearing_std [rad]: bearing and range_bearing. range_std [m]: range_bearing.
    position_std [m]: pose fix (x and y, per beacon: averaging n beacons divides it by
    sqrt(n)) and position fix (seed 002's sigma_d, multiplied by HDOP).
    heading_std [rad]: pose fix heading (also divided by sqrt(n)).
    """

    bearing_std: float = 0.05
    range_std: float = 0.1
    position_std: float = 0.1
    heading_std: float = 0.05


@dataclass(frozen=True)
class SensorReach:
    """What every sensor declares, of beacons or of other robots: its ``name`` and ``kind``,
    ``period`` [s] between readings, ``max_range`` [m], ``fov`` [rad] (centred on the
    heading) and ``detection_prob`` (each target in reach is read with that probability)."""

    name: str
    kind: str
    period: float = 0.1
    max_range: float = math.inf
    fov: float = 2.0 * math.pi
    detection_prob: float = 1.0


@dataclass(frozen=True)
class SensorSpec(SensorReach):
    """One sensor of the robot, as a scenario file describes it.

    Attributes
    ----------
    name : str
    kind : str
        A registered sensor kind (core/sensor_kinds.py): ``bearing``, ``range_bearing``,
        ``pose``, ``position``, ``range_finder``, or one registered later.
    period : float
        Time between readings [s]; a multiple of the scenario's dt.
    max_range : float
        Beacons further than this [m] are not seen (``inf``: no limit).
    fov : float
        Full field of view [rad] centred on the heading; ``2 pi`` sees all around.
    detection_prob : float
        Probability that a beacon in range and view is detected on a reading.
    outlier_rate : float
        Probability that a reading is replaced by a random one.
    min_beacons : int
        Pose / position fixes need at least this many beacons seen (1 and 2 by default).
    beacon_height : float
        Height [m] of the beacons above the receiver, for the HDOP of a position fix.
    noise : SensorNoise
        The true noise of the readings.
    correspondence : str
        ``"known"`` (each reading carries its beacon's ID) or ``"unknown"`` (beacon
        sensors only: every ID is -1, ``core/clutter.UNKNOWN_ID``; the filter associates).
    clutter_rate : float
        Mean number of false detections per reading (Poisson), unknown correspondence only.
    n_beams : int
        range_finder: beams per scan (0 for the other kinds).
    range_model : RangeModelParams or None
        range_finder: the beam model the readings are drawn from (its ``laser_max_range``
        is ``max_range``); None for the other kinds.
    occluded_by_walls : bool
        Beacon sensors in a world with walls: a beacon behind a wall is not seen (default).
        No effect in a world without walls.
    params : tuple of (str, float)
        The values of the keys the sensor's kind declares (core/sensor_kind.py's
        ``KindParam``): :meth:`param` reads one.
    """

    outlier_rate: float = 0.0
    min_beacons: int = 1
    beacon_height: float = 0.0
    noise: SensorNoise = field(default_factory=SensorNoise)
    correspondence: str = "known"
    clutter_rate: float = 0.0
    n_beams: int = 0
    range_model: RangeModelParams | None = None
    occluded_by_walls: bool = True
    params: tuple[tuple[str, float], ...] = ()

    def param(self, key: str) -> float:
        """The value of a key the sensor's kind declares (``SensorKind.params``)."""
        for k, v in self.params:
            if k == key:
                return v
        raise KeyError(f"sensor {self.name!r} ({self.kind}) has no parameter {key!r}")

    def fix_std(self, n_beacons: int, hdop_value: float = 1.0) -> np.ndarray:
        """Standard deviations of one fix row: pose ``[sx, sy, sth]`` or position ``[sx, sy]``."""
        if self.kind == "pose":
            s = 1.0 / math.sqrt(max(n_beacons, 1))
            n = self.noise
            return np.array([n.position_std * s, n.position_std * s, n.heading_std * s])
        if self.kind == "position":
            return np.full(2, self.noise.position_std * hdop_value)
        raise ValueError(f"fix_std is for pose and position sensors, not {self.kind!r}")

    def reading_std(self) -> np.ndarray:
        """Standard deviations of one beacon reading: ``[sb]`` or ``[sr, sb]``."""
        if self.kind == "bearing":
            return np.array([self.noise.bearing_std])
        if self.kind == "range_bearing":
            return np.array([self.noise.range_std, self.noise.bearing_std])
        raise ValueError(f"reading_std is for beacon sensors, not {self.kind!r}")


def in_view(spec: SensorSpec, poses: np.ndarray, bxy: np.ndarray) -> np.ndarray:
    """Boolean mask (R, n) of the beacons at ``bxy`` (n, 2) [m] within range and field of
    view of each pose (R, 3) [m, m, rad]; walls are not looked at. Portable maths (the
    truth's decision: the same on every machine)."""
    d = bxy[None, :, :] - poses[:, None, :2]
    in_range = pm.hypot(d[..., 0], d[..., 1]) <= spec.max_range
    if spec.fov >= 2.0 * math.pi:
        return in_range
    rel = wrap(relative_bearing(d[..., 0], d[..., 1], poses[:, 2:3], portable=True))
    return in_range & (np.abs(rel) <= 0.5 * spec.fov)


def visible_mask(spec: SensorSpec, poses: np.ndarray, world: World) -> np.ndarray:
    """Boolean mask (R, n) of the world's beacons each pose (R, 3) could see (no detection
    draw): in range and field of view and, in a world with walls when
    ``spec.occluded_by_walls``, in line of sight."""
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    vis = in_view(spec, poses, world.beacon_xy)
    if world.grid is None or not spec.occluded_by_walls or not vis.any():
        return vis
    r, b = np.nonzero(vis)
    vis[r, b] = line_of_sight(world.grid, poses[r, :2], world.beacon_xy[b])
    return vis


def visible_beacons(spec: SensorSpec, pose: np.ndarray, world: World) -> np.ndarray:
    """Boolean mask, shape (n,), of the beacons in range, field of view and (walls) line of
    sight of ``pose`` (no detection draw)."""
    return visible_mask(spec, np.asarray(pose, dtype=float)[None, :3], world)[0]


def sense(
    spec: SensorSpec, pose: np.ndarray, world: World, rng: np.random.Generator
) -> Measurement | None:
    """One reading of ``spec`` at the true ``pose``; None when nothing was measured.

    Beacon sensors return one row per detected beacon (None when none is detected); fixes
    return a single row when at least ``min_beacons`` beacons are detected.
    The draw of the built-in beacon and fix kinds (bearing, range_bearing, pose, position);
    a laser scan is drawn by :func:`sense_scan` (its kind's record, core/sensor_kinds.py).
    """
    n = len(world.beacons)
    d = MEASUREMENT_DIMS[spec.kind]
    # Fixed-size draws: the stream advances the same way whatever is seen.
    u_detect = rng.random(n)
    noise = rng.standard_normal((n, d)) if spec.kind in ("bearing", "range_bearing") else \
        rng.standard_normal((1, d))
    u_outlier = rng.random(max(n, 1))
    u_value = rng.random((max(n, 1), d))

    seen = visible_beacons(spec, pose, world) & (u_detect < spec.detection_prob)
    idx = np.flatnonzero(seen)
    ids = world.beacon_ids[idx]
    if spec.kind == "bearing":
        if idx.size == 0:
            return None
        z = (mm.bearing(pose, world.beacon_xy[idx], portable=True)[:, None]
             + noise[idx] * spec.noise.bearing_std)
        if spec.outlier_rate > 0.0:  # u < rate is never true otherwise: skip the empty indexing
            out = u_outlier[idx] < spec.outlier_rate
            z[out, 0] = -math.pi + 2.0 * math.pi * u_value[idx][out, 0]
        z[:, 0] = wrap(z[:, 0])
        return Measurement(spec.name, spec.kind, z, ids)
    if spec.kind == "range_bearing":
        if idx.size == 0:
            return None
        z = mm.range_bearing(pose, world.beacon_xy[idx], portable=True) + noise[idx] * spec.reading_std()
        if spec.outlier_rate > 0.0:
            out = u_outlier[idx] < spec.outlier_rate
            max_r = spec.max_range if math.isfinite(spec.max_range) else max(world.width, world.height)
            z[out, 0] = max_r * u_value[idx][out, 0]
            z[out, 1] = -math.pi + 2.0 * math.pi * u_value[idx][out, 1]
        z[:, 0] = np.abs(z[:, 0])
        z[:, 1] = wrap(z[:, 1])
        return Measurement(spec.name, spec.kind, z, ids)

    # Pose and position fixes.
    if idx.size < spec.min_beacons:
        return None
    h = float("nan")
    if spec.kind == "position":
        h = hdop(pose[:2], world.beacon_xy[idx], spec.beacon_height)
        if not math.isfinite(h):
            return None
        z = pose[:2] + noise[0] * spec.fix_std(idx.size, h)
    else:
        z = pose + noise[0] * spec.fix_std(idx.size)
        z[2] = wrap(z[2])
    if u_outlier[0] < spec.outlier_rate:
        xmin, ymin, xmax, ymax = world.bounds
        z[0] = xmin + (xmax - xmin) * u_value[0, 0]
        z[1] = ymin + (ymax - ymin) * u_value[0, 1]
        if spec.kind == "pose":
            z[2] = -math.pi + 2.0 * math.pi * u_value[0, 2]
    return Measurement(spec.name, spec.kind, z[None, :], ids, hdop=h)


def sense_scan(spec: SensorSpec, pose: np.ndarray, world: World,
               rng: np.random.Generator) -> Measurement:
    """One laser scan at the true ``pose``: rows ``[range, beam angle]`` [m, rad], the ranges
    drawn from the beam model around the ray-cast distances to the walls; a beam with no
    wall within max_range reads max_range (no return) unless a short or random reading is
    drawn (a world without walls: every beam)."""
    model = spec.range_model if spec.range_model is not None else \
        RangeModelParams(laser_max_range=spec.max_range)
    if world.grid is None:
        rel = beam_angles(spec.n_beams, spec.fov)
        expected = np.full(spec.n_beams, model.laser_max_range)
    else:
        rel, expected = scan(world.grid, pose, spec.n_beams, spec.fov, model.laser_max_range)
    ranges = sample_beam(expected, model, rng)
    # A beam that meets no wall within range gets no return: it reads max_range. Its hit
    # part (drawn within a few sigma_hit below max_range) is snapped to it; its short and
    # random readings stay (a random reading in that last band is snapped too: negligible).
    no_return = (expected >= model.laser_max_range) & \
        (ranges > model.laser_max_range - 5.0 * model.sigma_hit)
    ranges[no_return] = model.laser_max_range
    z = np.column_stack([ranges, rel])
    return Measurement(spec.name, spec.kind, z, np.zeros(0, dtype=int))   # no beacon
