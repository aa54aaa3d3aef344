"""StudentEKF: the extended Kalman filter that docs/writing-a-filter.md builds, in one file.

It uses only what the core provides: the velocity motion model and its Jacobians
(``beacon_sim.core.motion``), the measurement models and their Jacobians
(``beacon_sim.core.measurement_models``) and the noise the scenario tells the filter
(``ctx.motion_noise``, ``ctx.sensor(name)``). It handles all four sensor kinds.

Try it::

    beacon-sim play --filter examples/student_ekf.py:StudentEKF --filter ekf
    beacon-sim run default --filter examples/student_ekf.py:StudentEKF
    beacon-sim check examples/student_ekf.py:StudentEKF
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from beacon_sim.api import (
    Control,
    FilterBase,
    FilterContext,
    GaussianBelief,
    Measurement,
    broad_gaussian,
    motion,
    wrap,
)
from beacon_sim.api import (
    measurement_models as mm,
)


class StudentEKF(FilterBase):
    """EKF over the pose ``[x, y, theta]`` [m, m, rad]."""

    def __init__(self, ctx: FilterContext):
        super().__init__(ctx)
        # beacon id -> (x, y) [m], to look up the beacon each reading names
        self.beacons = {b.id: (b.x, b.y) for b in ctx.world.beacons}
        self.mean = np.zeros(3)
        self.cov = np.eye(3)

    def reset(self, initial: GaussianBelief | None) -> None:
        initial = initial or broad_gaussian(self.ctx.world)
        self.mean = np.array(initial.mean, dtype=float)
        self.cov = np.array(initial.cov, dtype=float)

    def predict(self, control: Control, dt: float) -> None:
        # F = d move / d pose and Q = B M B^T (+ pose noise), both at the prior mean
        F = motion.jacobian_state(self.mean, control.v, dt)
        Q = self.ctx.motion_noise.process_cov(self.mean, control.v, control.omega, dt)
        # mean' = g(mean, u);  P' = F P F^T + Q
        self.mean = motion.move(self.mean, control.v, control.omega, dt)
        self.cov = F @ self.cov @ F.T + Q

    def update(self, measurements: Sequence[Measurement]) -> None:
        for m in measurements:
            spec = self.ctx.sensor(m.sensor)
            if m.kind in ("bearing", "range_bearing"):
                xy = np.array([self.beacons[int(i)] for i in m.beacon_ids])
                std = spec.reading_std()
                for row, beacon in zip(m.z, xy, strict=True):
                    if m.kind == "bearing":
                        h = mm.bearing(self.mean, beacon)          # shape (1,)
                        H = mm.bearing_jacobian(self.mean, beacon)  # shape (1, 3)
                        y = wrap(row - h)
                    else:
                        h = mm.range_bearing(self.mean, beacon)[0]            # shape (2,)
                        H = mm.range_bearing_jacobian(self.mean, beacon)[0]   # shape (2, 3)
                        y = row - h
                        y[1] = wrap(y[1])
                    self._correct(y, H, np.diag(std**2))
            elif m.kind == "pose":
                y = m.z[0] - mm.pose_fix(self.mean)
                y[2] = wrap(y[2])
                std = spec.fix_std(len(m.beacon_ids))
                self._correct(y, np.eye(3), np.diag(std**2))
            elif m.kind == "position":
                y = m.z[0] - mm.position_fix(self.mean)
                std = spec.fix_std(len(m.beacon_ids), m.hdop)
                self._correct(y, mm.POSITION_H, np.diag(std**2))

    def _correct(self, y, H, R) -> None:
        """One Kalman correction with innovation ``y`` (angles already wrapped)."""
        P = self.cov
        S = H @ P @ H.T + R                 # innovation covariance
        K = np.linalg.solve(S, H @ P).T     # K = P H^T S^-1 (S and P symmetric)
        self.mean = self.mean + K @ y
        self.mean[2] = wrap(self.mean[2])
        I_KH = np.eye(3) - K @ H
        # Joseph form: stays symmetric positive definite despite rounding
        self.cov = I_KH @ P @ I_KH.T + K @ R @ K.T

    def estimate(self) -> tuple[np.ndarray, np.ndarray]:
        return self.mean.copy(), self.cov.copy()
