"""Expected measurements h(pose) and their Jacobians H = dh/dpose, for every sensor kind.

Known correspondence: each reading names its beacon. Bearings are relative to the robot's
heading and wrapped to [-pi, pi). The simulation computes its readings with ``portable=True``
(core/portable_math.py: the same bits on every machine); filters use numpy's fast kernels,
which agree to a few ulp. Functions take one pose of shape (3,) unless they say
otherwise; the ``*_many`` forms take poses of shape (N, 3) for particle and grid filters.
"""

from __future__ import annotations

import math

import numpy as np

from beacon_sim.core import portable_math as pm
from beacon_sim.core.angles import wrap


def relative_bearing(dx, dy, theta, out=None, portable: bool = False):
    """The bearing model, the one place it is written: the direction [rad] of the offset
    ``(dx, dy)`` [m] (beacon minus robot, world frame) seen from heading ``theta`` [rad],
    ``atan2(dy, dx) - theta`` (seed 000 eq. 6), NOT wrapped: callers wrap it, or the
    innovation ``wrap(z - h)``, as their arithmetic needs. Arrays broadcast; ``out``, an
    array of the result's shape, receives it without allocating. ``portable``: the
    portable atan2 (the simulation's readings) instead of numpy's."""
    return np.subtract(pm.atan2(dy, dx) if portable else np.arctan2(dy, dx), theta, out=out)


def relative_bearing_scalar(dx: float, dy: float, theta: float, portable: bool = False) -> float:
    """:func:`relative_bearing` for Python floats with ``math.atan2`` (no array overhead:
    the per-reading hot paths; numpy's array atan2 may round differently in the last bit).
    ``portable``: the portable atan2 (the simulation's steering and readings)."""
    return (pm.atan2_1(dy, dx) if portable else math.atan2(dy, dx)) - theta


def bearing(pose, beacon_xy, portable: bool = False):
    """Bearing to each beacon [rad], shape (m,): ``atan2(yb - y, xb - x) - theta`` (seed 000
    eq. 6). ``portable``: with the portable kernels (the simulation's readings)."""
    d = np.asarray(beacon_xy, dtype=float).reshape(-1, 2) - np.asarray(pose[:2], dtype=float)
    return wrap(relative_bearing(d[:, 0], d[:, 1], pose[2], portable=portable))


def bearing_jacobian(pose, beacon_xy):
    """H for bearings, shape (m, 3): ``[dy/q, -dx/q, -1]`` with ``(dx, dy) = beacon - robot``, q = r^2."""
    d = np.asarray(beacon_xy, dtype=float).reshape(-1, 2) - np.asarray(pose[:2], dtype=float)
    q = np.sum(d * d, axis=1)
    H = np.empty((d.shape[0], 3))
    H[:, 0] = d[:, 1] / q
    H[:, 1] = -d[:, 0] / q
    H[:, 2] = -1.0
    return H


def range_bearing(pose, beacon_xy, portable: bool = False):
    """Range [m] and bearing [rad] to each beacon, shape (m, 2) (seed 001). ``portable``:
    with the portable kernels (the simulation's readings)."""
    d = np.asarray(beacon_xy, dtype=float).reshape(-1, 2) - np.asarray(pose[:2], dtype=float)
    out = np.empty((d.shape[0], 2))
    out[:, 0] = pm.hypot(d[:, 0], d[:, 1]) if portable else np.hypot(d[:, 0], d[:, 1])
    out[:, 1] = wrap(relative_bearing(d[:, 0], d[:, 1], pose[2], portable=portable))
    return out


def range_bearing_jacobian(pose, beacon_xy):
    """H for range-bearing, shape (m, 2, 3) (seed 001's H_k, one 2x3 block per beacon)."""
    d = np.asarray(beacon_xy, dtype=float).reshape(-1, 2) - np.asarray(pose[:2], dtype=float)
    q = np.sum(d * d, axis=1)
    r = np.sqrt(q)
    H = np.zeros((d.shape[0], 2, 3))
    H[:, 0, 0] = -d[:, 0] / r
    H[:, 0, 1] = -d[:, 1] / r
    H[:, 1, 0] = d[:, 1] / q
    H[:, 1, 1] = -d[:, 0] / q
    H[:, 1, 2] = -1.0
    return H


def pose_fix(pose):
    """A pose fix measures the pose itself: h = pose, H = I (seed 003's C = I)."""
    return np.asarray(pose, dtype=float).copy()


def position_fix(pose):
    """A position fix measures x, y: h = pose[:2], H = [[1, 0, 0], [0, 1, 0]]."""
    return np.asarray(pose[:2], dtype=float).copy()


POSITION_H = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def bearing_many(poses, beacon_xy):
    """Bearings from many poses, shape (N, m) [rad]."""
    poses = np.asarray(poses, dtype=float)
    b = np.asarray(beacon_xy, dtype=float).reshape(-1, 2)
    dx = b[None, :, 0] - poses[:, 0:1]
    dy = b[None, :, 1] - poses[:, 1:2]
    return wrap(relative_bearing(dx, dy, poses[:, 2:3]))


def range_many(poses, beacon_xy):
    """Ranges from many poses, shape (N, m) [m]."""
    poses = np.asarray(poses, dtype=float)
    b = np.asarray(beacon_xy, dtype=float).reshape(-1, 2)
    return np.hypot(b[None, :, 0] - poses[:, 0:1], b[None, :, 1] - poses[:, 1:2])
