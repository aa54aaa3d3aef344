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
        self.xy = np.array(ctx.world.beacon_xy, dtype=float).reshape(-1, 2)
        self.row = {int(b.id): i for i, b in enumerate(ctx.world.beacons)}
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

    def beacons(self, ids) -> np.ndarray:
        """Positions (k, 2) [m] of the beacons with these IDs."""
        try:
            return self.xy[[self.row[i] for i in ids.tolist()]]
        except KeyError as exc:
            raise FilterError(f"reading from beacon {exc.args[0]}, which is not on the map") from None

    def reading_variance(self, sensor: str) -> tuple[float, ...]:
        var = self.reading_var.get(sensor)
        if var is None:
            var = tuple(float(v) ** 2 for v in self.spec(sensor).reading_std())
        return var

    def fix_var(self, m: Measurement) -> list[float]:
        """Variances of a pose ``[x, y, theta]`` or position ``[x, y]`` fix row."""
        std = self.spec(m.sensor).fix_std(len(m.beacon_ids), m.hdop)
        return [float(s) ** 2 for s in std]


@dataclass
class StackedReadings:
    """One tick's readings as one vector. Rows are ordered measurement by measurement,
    reading by reading, component by component (range before bearing).

    ``angle`` is a boolean mask of the angle rows; ``angle_sel`` selects the same rows as a
    slice when it can (a view, cheaper than a mask on the hot path).
    """

    z: np.ndarray          # (m,) measured values [m or rad]
    r: np.ndarray          # (m,) noise variances [m^2 or rad^2]
    angle: np.ndarray      # (m,) bool: row is an angle (wrap its residuals)
    angle_sel: object      # slice or index array of the angle rows (None: no angle row)
    blocks: list           # (kind, start, stop, beacon xy (k, 2) or None)

    def __len__(self) -> int:
        return int(self.z.shape[0])

    def predict(self, poses: np.ndarray, wrap: bool = True) -> np.ndarray:
        """Expected readings h(pose) for poses of shape (N, 3): shape (N, m), angles wrapped
        (``wrap=False`` leaves them unwrapped, for callers that wrap residuals anyway)."""
        out = np.empty((poses.shape[0], self.z.shape[0]))
        x = poses[:, 0:1]
        y = poses[:, 1:2]
        th = poses[:, 2:3]
        for kind, a, b, bxy in self.blocks:
            if kind == "bearing":
                np.subtract(np.arctan2(bxy[:, 1] - y, bxy[:, 0] - x), th, out=out[:, a:b])
            elif kind == "range_bearing":
                dx = bxy[:, 0] - x
                dy = bxy[:, 1] - y
                np.hypot(dx, dy, out=out[:, a:b:2])
                np.subtract(np.arctan2(dy, dx), th, out=out[:, a + 1:b:2])
            elif kind == "pose":
                out[:, a:b] = poses
            else:  # position
                out[:, a:b] = poses[:, :2]
        sel = self.angle_sel
        if wrap and sel is not None:  # wrap the angle rows to [-pi, pi)
            out[:, sel] = (out[:, sel] + np.pi) % (2.0 * np.pi) - np.pi
        return out


_ANGLE_PATTERN = {"bearing": (True,), "range_bearing": (False, True), "pose": (False, False, True),
                  "position": (False, False)}


def stack(models: ReadingModels, measurements: Iterable[Measurement],
          kinds: Sequence[str] = ("bearing", "range_bearing", "pose", "position")
          ) -> StackedReadings | None:
    """Stack the readings of the given ``kinds``; None when there is nothing to use."""
    zs, rs, angles, blocks = [], [], [], []
    m0 = 0
    for m in measurements:
        if m.kind not in kinds or len(m) == 0:
            continue
        if m.kind in BEACON_KINDS:
            var = models.reading_variance(m.sensor)
            bxy = models.beacons(m.beacon_ids)
            k = bxy.shape[0]
            rs.extend(var * k)
            angles.extend(_ANGLE_PATTERN[m.kind] * k)
            n = k * len(var)
        else:
            var = models.fix_var(m)
            rs.extend(var)
            angles.extend(_ANGLE_PATTERN[m.kind])
            bxy = None
            n = len(var)
        zs.append(m.z.reshape(-1))
        blocks.append((m.kind, m0, m0 + n, bxy))
        m0 += n
    if not blocks:
        return None
    z = zs[0] if len(zs) == 1 else np.concatenate(zs)
    angle = np.array(angles)
    if len(blocks) == 1 and blocks[0][0] != "position":
        kind = blocks[0][0]
        sel = slice(None) if kind == "bearing" else slice(1, None, 2) if kind == "range_bearing" \
            else slice(2, 3)
    else:
        sel = np.flatnonzero(angle) if any(angles) else None
    return StackedReadings(np.asarray(z, dtype=float), np.array(rs), angle, sel, blocks)


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
