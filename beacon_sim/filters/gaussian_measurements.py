"""Stacking one tick's readings for the Gaussian filters.

All readings of a tick (any sensors, any number of beacons) become one measurement vector
``z`` (m,), one diagonal noise variance vector ``r`` (m,) and a flag per row saying whether
the row is an angle (bearing, or the heading of a pose fix), whose residuals must be
wrapped. ``StackedReadings.predict(poses)`` evaluates the stacked model h for many poses at
once (the UKF's sigma points); the EKF uses the same rows with its own scalar Jacobians.

Noise comes from the filter's context: ``ctx.sensor(name).reading_std()`` for beacon
readings, ``fix_std(len(beacon_ids), hdop)`` for pose and position fixes.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from beacon_sim.core.motion import MotionNoise
from beacon_sim.core.types import Measurement
from beacon_sim.filters.base import FilterContext, FilterError

BEACON_KINDS = ("bearing", "range_bearing")
FIX_KINDS = ("pose", "position")


class ReadingModels:
    """Per-filter lookup tables built once from the context: beacon positions by ID [m]
    and the told noise of each sensor (so the hot path does no searching)."""

    def __init__(self, ctx: FilterContext):
        self.ctx = ctx
        self.beacon_xy = {int(b.id): (float(b.x), float(b.y)) for b in ctx.world.beacons}
        self.specs = {s.name: s for s in ctx.sensors}
        self.reading_var = {s.name: tuple(float(v) ** 2 for v in s.reading_std())
                            for s in ctx.sensors if s.kind in BEACON_KINDS}

    def spec(self, name: str):
        try:
            return self.specs[name]
        except KeyError:
            return self.ctx.sensor(name)  # raises FilterError with a clear message

    def beacon(self, beacon_id: int) -> tuple[float, float]:
        try:
            return self.beacon_xy[beacon_id]
        except KeyError:
            raise FilterError(f"reading from beacon {beacon_id}, which is not on the map") from None

    def fix_var(self, m: Measurement) -> list[float]:
        """Variances of a pose ``[x, y, theta]`` or position ``[x, y]`` fix row."""
        std = self.spec(m.sensor).fix_std(len(m.beacon_ids), m.hdop)
        return [float(s) ** 2 for s in std]


@dataclass
class StackedReadings:
    """One tick's readings as one vector. Rows are ordered measurement by measurement,
    reading by reading, component by component (range before bearing)."""

    z: np.ndarray          # (m,) measured values [m or rad]
    r: np.ndarray          # (m,) noise variances [m^2 or rad^2]
    angle: np.ndarray      # (m,) bool: row is an angle (wrap its residuals)
    blocks: list           # (kind, start, stop, beacon xy (k, 2) or None)

    def __len__(self) -> int:
        return int(self.z.shape[0])

    def predict(self, poses: np.ndarray) -> np.ndarray:
        """Expected readings h(pose) for poses of shape (N, 3): shape (N, m), angles wrapped."""
        out = np.empty((poses.shape[0], self.z.shape[0]))
        x = poses[:, 0:1]
        y = poses[:, 1:2]
        th = poses[:, 2:3]
        for kind, a, b, bxy in self.blocks:
            if kind == "bearing":
                out[:, a:b] = np.arctan2(bxy[:, 1] - y, bxy[:, 0] - x) - th
            elif kind == "range_bearing":
                dx = bxy[:, 0] - x
                dy = bxy[:, 1] - y
                out[:, a:b:2] = np.hypot(dx, dy)
                out[:, a + 1:b:2] = np.arctan2(dy, dx) - th
            elif kind == "pose":
                out[:, a:b] = poses
            else:  # position
                out[:, a:b] = poses[:, :2]
        # Wrap the angle rows to [-pi, pi).
        ang = out[:, self.angle]
        out[:, self.angle] = (ang + np.pi) % (2.0 * np.pi) - np.pi
        return out


def stack(models: ReadingModels, measurements: Iterable[Measurement],
          kinds: Sequence[str] = ("bearing", "range_bearing", "pose", "position")
          ) -> StackedReadings | None:
    """Stack the readings of the given ``kinds``; None when there is nothing to use."""
    zs, rs, angles, blocks = [], [], [], []
    m0 = 0
    for m in measurements:
        if m.kind not in kinds or len(m) == 0:
            continue
        z = np.asarray(m.z, dtype=float)
        if m.kind in BEACON_KINDS:
            var = models.reading_var.get(m.sensor)
            if var is None:
                var = tuple(float(v) ** 2 for v in models.spec(m.sensor).reading_std())
            bxy = np.array([models.beacon(int(i)) for i in m.beacon_ids.tolist()]).reshape(-1, 2)
            k = bxy.shape[0]
            zs.append(z.reshape(-1))
            rs.append(np.tile(var, k))
            angles.append(np.tile([False, True] if m.kind == "range_bearing" else [True], k))
            n = k * len(var)
        else:
            row = z.reshape(-1)
            zs.append(row)
            rs.append(np.array(models.fix_var(m)))
            angles.append(np.array([False, False, True][: row.shape[0]]))
            bxy = None
            n = row.shape[0]
        blocks.append((m.kind, m0, m0 + n, bxy))
        m0 += n
    if not blocks:
        return None
    if len(zs) == 1:
        return StackedReadings(zs[0], rs[0], angles[0], blocks)
    return StackedReadings(np.concatenate(zs), np.concatenate(rs), np.concatenate(angles), blocks)


def process_cov_terms(noise, theta: float, v: float, omega: float, dt: float) -> tuple[float, ...]:
    """``(q00, q01, q02, q11, q12, q22)`` of ``noise.process_cov(pose, v, omega, dt)`` as floats.

    Q = B M B^T + diag(pose_std^2) with B = [[dt cos, 0], [dt sin, 0], [0, dt]] and
    M = diag(sigma_v^2, sigma_omega^2), written out for a plain ``MotionNoise`` (no numpy
    call); any other noise object is asked for its ``process_cov``.
    """
    if type(noise) is not MotionNoise:
        q = noise.process_cov(np.array([0.0, 0.0, theta]), v, omega, dt).tolist()
        return q[0][0], q[0][1], q[0][2], q[1][1], q[1][2], q[2][2]
    c, s = math.cos(theta), math.sin(theta)
    sv = noise.v_std + noise.v_frac * abs(v)
    sw = noise.omega_std + noise.omega_frac * abs(omega)
    qv = dt * dt * sv * sv
    ps = noise.pose_std
    return (qv * c * c + ps[0] * ps[0], qv * c * s, 0.0, qv * s * s + ps[1] * ps[1], 0.0,
            dt * dt * sw * sw + ps[2] * ps[2])
