"""Geometry of beacons that give distances: slant ranges to beacons mounted ``beacon_height``
metres above the receiver (ceiling beacons, the receiver's height known), their Jacobians,
the coverage cone of beacons that point down, and the checks a scenario with such beacons
must pass. Shared by the ``range``, ``tdoa`` and ``tdoa_fix`` kinds.

Frames and units: poses ``[x, y, theta]`` [m, m, rad] in the world frame; ranges [m]. A
beacon at ``(bx, by)`` is ``h = spec.beacon_height`` above the receiver, so the range from a
pose is ``r = sqrt((x - bx)^2 + (y - by)^2 + h^2)`` (h = 0: beacons at the receiver's
height, as UWB anchors in a plane). ``max_range`` is horizontal, as for every beacon sensor.
The cone: a beacon that points down covers the receivers within ``cone_half_angle`` [rad]
of its vertical axis (``pi / 2``: no cone).
"""

from __future__ import annotations

import math

import numpy as np

from beacon_sim.core import portable_math as pm
from beacon_sim.core.sensor_kind import KindParam
from beacon_sim.core.sensors import SensorSpec, visible_mask
from beacon_sim.core.world import World

#: The coverage cone's half-angle key (both distance kinds declare it).
CONE = KindParam("cone_half_angle", 0.5 * math.pi, 1e-3, 0.5 * math.pi,
                 "half-angle [rad] of a beacon's coverage cone about its downward axis "
                 "(pi / 2: no cone)")

#: Two beacons nearer than this [m] count as one point (a hostile layout).
MIN_BEACON_SEPARATION = 1e-6


def slant_ranges(poses: np.ndarray, bxy: np.ndarray, height: float) -> np.ndarray:
    """Ranges (N, m) [m] from poses (N, >= 2) to beacons (m, 2) ``height`` above them.
    Only +, *, sqrt (correctly rounded: the same bits on every machine)."""
    dx = poses[:, 0:1] - bxy[None, :, 0]
    dy = poses[:, 1:2] - bxy[None, :, 1]
    return np.sqrt(dx * dx + dy * dy + height * height)


def range_jacobian(pose: np.ndarray, bxy: np.ndarray, height: float) -> np.ndarray:
    """d r / d pose (m, 3) at one pose: ``[(x - bx) / r, (y - by) / r, 0]``."""
    d = np.asarray(pose, dtype=float)[None, :2] - bxy
    r = np.sqrt(np.sum(d * d, axis=1) + height * height)
    r = np.maximum(r, 1e-12)
    return np.column_stack([d[:, 0] / r, d[:, 1] / r, np.zeros(len(r))])


def in_cone(spec: SensorSpec, poses: np.ndarray, bxy: np.ndarray) -> np.ndarray:
    """Mask (N, m): receivers within each beacon's coverage cone (all when there is none):
    ``horizontal * cos(a) <= height * sin(a)``, portable sine and cosine."""
    a = spec.param("cone_half_angle") if spec.params else CONE.default
    if a >= 0.5 * math.pi:
        return np.ones((poses.shape[0], bxy.shape[0]), dtype=bool)
    s, c = pm.sincos1(a)
    dx = poses[:, 0:1] - bxy[None, :, 0]
    dy = poses[:, 1:2] - bxy[None, :, 1]
    return np.sqrt(dx * dx + dy * dy) * c <= spec.beacon_height * s


def covered_mask(spec: SensorSpec, poses: np.ndarray, world: World) -> np.ndarray:
    """Mask (N, n) of the world's beacons each pose (N, 3) can hear (no detection draw):
    in range, field of view, line of sight (walls) and coverage cone."""
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    return visible_mask(spec, poses, world) & in_cone(spec, poses, world.beacon_xy)


def check_layout(spec: SensorSpec, world: World, least: int) -> str | None:
    """Why the beacons cannot give distances to ``spec`` (None: they can): fewer than
    ``least`` beacons, or two at one point. A ``key: value: expected`` text."""
    xy = world.beacon_xy
    if len(xy) < least:
        return (f"world.beacons: {len(xy)} beacon(s): expected at least {least} for a "
                f"{spec.kind} sensor")
    for i in range(len(xy)):
        d = np.hypot(*(xy[i + 1:] - xy[i]).T)
        j = np.flatnonzero(d < MIN_BEACON_SEPARATION)
        if j.size:
            a, b = world.beacon_ids[i], world.beacon_ids[i + 1 + j[0]]
            return (f"world.beacons: beacons {a} and {b} at one point ({xy[i, 0]:g}, {xy[i, 1]:g}): "
                    f"expected distinct positions for a {spec.kind} sensor")
    return None


def exponential(u: np.ndarray, mean: float) -> np.ndarray:
    """Exponential draws [m] of ``mean`` from uniforms u in [0, 1), portable log."""
    return -mean * pm.log(1.0 - u)


__all__ = ["CONE", "MIN_BEACON_SEPARATION", "check_layout", "covered_mask", "exponential",
           "in_cone", "range_jacobian", "slant_ranges"]
