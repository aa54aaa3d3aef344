"""What the SLAM filters share (docs/slam.md): the landmark observation model with its
Jacobians in the pose *and* the landmark, the inverse model that places a new landmark from
one range-bearing reading, and a base class that sorts a tick's readings into anchors
(beacons whose position the filter was given), known IDs and unlabelled rows.

Frames and units as everywhere (docs/architecture.md): world frame, metres, radians, y up.
A landmark is a point ``m = (mx, my)`` [m]; a reading is ``[b]`` (bearing) or ``[r, b]``
(range-bearing) in the robot frame. Every function here works on N poses at once (the
particles of FastSLAM; the EKF passes N = 1).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.clutter import UNKNOWN_ID
from beacon_sim.core.types import Measurement
from beacon_sim.filters.base import FilterBase, FilterContext, FilterError, LandmarkMap

#: The reading kinds a SLAM filter can map landmarks from, and the width of one row.
SLAM_KINDS = {"bearing": 1, "range_bearing": 2}


def observe(kind: str, poses: np.ndarray, lm: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Expected reading of landmarks ``lm`` (N, 2) [m] from ``poses`` (N, 3), and Jacobians.

    With ``(dx, dy) = m - (x, y)``, ``q = dx^2 + dy^2``, ``r = sqrt(q)``:
    range ``h_r = r``, bearing ``h_b = atan2(dy, dx) - theta`` (wrapped)::

        dh_r/d(x, y, theta) = [-dx/r, -dy/r, 0]     dh_r/d(mx, my) = [dx/r, dy/r]
        dh_b/d(x, y, theta) = [dy/q, -dx/q, -1]     dh_b/d(mx, my) = [-dy/q, dx/q]

    Returns
    -------
    zhat : ndarray, shape (N, d) [m, rad]   (d = 1: bearing; 2: range, bearing)
    Hx : ndarray, shape (N, d, 3)
    Hm : ndarray, shape (N, d, 2)
    """
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    lm = np.asarray(lm, dtype=float).reshape(-1, 2)
    dx = lm[:, 0] - poses[:, 0]
    dy = lm[:, 1] - poses[:, 1]
    q = dx * dx + dy * dy
    n = dx.shape[0]
    b = wrap(np.arctan2(dy, dx) - poses[:, 2])
    if kind == "bearing":
        zhat = b[:, None]
        Hx = np.zeros((n, 1, 3))
        Hm = np.zeros((n, 1, 2))
        rows = 0
    elif kind == "range_bearing":
        r = np.sqrt(q)
        zhat = np.stack([r, b], axis=1)
        Hx = np.zeros((n, 2, 3))
        Hm = np.zeros((n, 2, 2))
        Hx[:, 0, 0] = -dx / r
        Hx[:, 0, 1] = -dy / r
        Hm[:, 0, 0] = dx / r
        Hm[:, 0, 1] = dy / r
        rows = 1
    else:
        raise FilterError(f"SLAM: cannot map landmarks from {kind!r} readings (expected one of "
                          f"{', '.join(SLAM_KINDS)})")
    Hx[:, rows, 0] = dy / q
    Hx[:, rows, 1] = -dx / q
    Hx[:, rows, 2] = -1.0
    Hm[:, rows, 0] = -dy / q
    Hm[:, rows, 1] = dx / q
    return zhat, Hx, Hm


def innovation(z: np.ndarray, zhat: np.ndarray) -> np.ndarray:
    """``z - zhat`` (..., d) with the bearing (last column) wrapped to [-pi, pi)."""
    nu = np.asarray(z, dtype=float) - zhat
    nu[..., -1] = wrap(nu[..., -1])
    return nu


def place(poses: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Direct initialisation: the landmark a range-bearing reading ``z = [r, b]`` puts at
    ``(x + r cos(theta + b), y + r sin(theta + b))``, from N poses (N, 3).

    Returns
    -------
    lm : ndarray, shape (N, 2) [m]
    Gx : ndarray, shape (N, 2, 3)   d lm / d(x, y, theta)
    Gz : ndarray, shape (N, 2, 2)   d lm / d(r, b)
    """
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    r, b = float(z[0]), float(z[1])
    a = poses[:, 2] + b
    c, s = np.cos(a), np.sin(a)
    n = poses.shape[0]
    lm = np.stack([poses[:, 0] + r * c, poses[:, 1] + r * s], axis=1)
    Gx = np.zeros((n, 2, 3))
    Gx[:, 0, 0] = 1.0
    Gx[:, 1, 1] = 1.0
    Gx[:, 0, 2] = -r * s
    Gx[:, 1, 2] = r * c
    Gz = np.empty((n, 2, 2))
    Gz[:, 0, 0] = c
    Gz[:, 0, 1] = -r * s
    Gz[:, 1, 0] = s
    Gz[:, 1, 1] = r * c
    return lm, Gx, Gz


@dataclass(frozen=True)
class Reading:
    """One row of a beacon measurement as a SLAM filter sees it.

    ``beacon_id`` is the ID the sensor reported (``UNKNOWN_ID`` = -1 without correspondence);
    ``anchor`` is the anchor's position [m] when the ID names a beacon on the given map.
    """

    kind: str
    z: np.ndarray
    R: np.ndarray
    beacon_id: int
    anchor: tuple[float, float] | None
    sensor: str = ""


class SlamFilterBase(FilterBase):
    """Bookkeeping every SLAM filter needs: the anchors (``ctx.world.beacons``: every beacon
    on a known map, the anchors on an unknown one) and a tick's readings split into rows.

    A subclass implements ``reset``, ``predict``, ``update``, ``estimate`` and
    ``landmarks() -> LandmarkMap`` (its estimated landmarks, the anchors not included).
    """

    sensor_kinds: ClassVar[tuple[str, ...]] = tuple(SLAM_KINDS)

    def __init__(self, ctx: FilterContext):
        super().__init__(ctx)
        self.anchors = {int(b.id): (float(b.x), float(b.y)) for b in ctx.world.beacons}
        self.noise = {s.name: np.diag(np.asarray(s.reading_std(), dtype=float) ** 2)
                      for s in ctx.sensors if s.kind in SLAM_KINDS}

    def readings(self, measurements: Sequence[Measurement]) -> Iterator[Reading]:
        """The beacon rows of a tick, in order (pose and position fixes are skipped)."""
        for m in measurements:
            if m.kind not in SLAM_KINDS:
                continue
            R = self.noise.get(m.sensor)
            if R is None:
                self.ctx.sensor(m.sensor)  # raises the one-line FilterError
                raise FilterError(f"sensor {m.sensor!r} is not a bearing or range-bearing sensor")
            for z, bid in zip(np.asarray(m.z, dtype=float), np.asarray(m.beacon_ids).tolist(),
                              strict=True):
                bid = int(bid)
                yield Reading(m.kind, z, R, bid, self.anchors.get(bid) if bid != UNKNOWN_ID else None,
                              m.sensor)

    def landmarks(self) -> LandmarkMap:
        raise NotImplementedError


def unknown(reading: Reading) -> bool:
    """True when the reading carries no beacon ID."""
    return reading.beacon_id == UNKNOWN_ID
