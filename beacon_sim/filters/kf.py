"""The linear Kalman filter of the classroom assignment (seed 003).

State ``mu = [x, y, theta]`` [m, m, rad], control ``u = [v, omega]``::

    predict:  mu = A mu + B(theta) u        A = I, B = [[dt cos th, 0], [dt sin th, 0], [0, dt]]
              Sigma = A Sigma A^T + R       R: the motion noise (MotionNoise.process_cov)
    update:   K = Sigma C^T (C Sigma C^T + Q)^-1
              mu = mu + K wrap(z - C mu)    heading innovation wrapped
              Sigma = (I - K C) Sigma (I - K C)^T + K Q K^T     (Joseph form)

(The seed's letters: R is the motion noise, Q the sensor noise.) B is evaluated at the
current heading, so the model is linear in the state for a given heading, as in the
assignment. Measurements:

- ``pose`` fix (the assignment's sensor): C = I, noise std ``fix_std(n_beacons)``;
- ``position`` fix: C = [I2 0], noise std ``position_std * HDOP``.

Bearing and range-bearing readings are *ignored*: they are not linear in the state (use
``ekf`` or ``ukf`` for them). ``beacon-sim check kf`` therefore runs on assignment_kf.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

import numpy as np

from beacon_sim.core import motion
from beacon_sim.core.angles import wrap
from beacon_sim.core.types import Control, Measurement
from beacon_sim.filters.base import FilterBase, FilterContext, GaussianBelief, broad_gaussian

I3 = np.eye(3)
C_POSE = I3
C_POSITION = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


class KalmanFilter(FilterBase):
    """Linear KF with A = I, B(theta), and C = I (pose fix) or [I2 0] (position fix)."""

    defaults: ClassVar[dict] = {}
    sensor_kinds: ClassVar[tuple[str, ...]] = ("pose", "position")

    def __init__(self, ctx: FilterContext):
        super().__init__(ctx)
        self.mean = np.zeros(3)
        self.cov = np.eye(3)
        self.reset(None)

    def reset(self, initial: GaussianBelief | None) -> None:
        initial = initial or broad_gaussian(self.ctx.world)
        self.mean = np.array(initial.mean, dtype=float)
        self.mean[2] = wrap(self.mean[2])
        cov = np.array(initial.cov, dtype=float)
        self.cov = 0.5 * (cov + cov.T)

    def estimate(self) -> tuple[np.ndarray, np.ndarray]:
        return self.mean.copy(), self.cov.copy()

    def predict(self, control: Control, dt: float) -> None:
        u = np.array([control.v, control.omega], dtype=float)
        B = motion.jacobian_control(self.mean, dt)                      # B(theta), seed 003
        R = self.ctx.motion_noise.process_cov(self.mean, control.v, control.omega, dt)
        mu = self.mean + B @ u                                          # A = I
        mu[2] = wrap(mu[2])
        self.mean = mu
        self.cov = self.cov + R                                         # A Sigma A^T + R

    def update(self, measurements: Sequence[Measurement]) -> None:
        rows_C, rows_nu, var = [], [], []
        for m in measurements:
            if m.kind not in self.sensor_kinds or len(m) == 0:
                continue  # bearing / range-bearing: not linear, ignored by this filter
            z = np.asarray(m.z, dtype=float).reshape(-1)
            std = self.ctx.sensor(m.sensor).fix_std(len(m.beacon_ids), m.hdop)
            if m.kind == "pose":
                nu = z - self.mean
                nu[2] = wrap(nu[2])                                     # heading innovation
                rows_C.append(C_POSE)
            else:
                nu = z - self.mean[:2]
                rows_C.append(C_POSITION)
            rows_nu.append(nu)
            var.append(np.square(std))
        if not rows_C:
            return
        C = np.vstack(rows_C)
        nu = np.concatenate(rows_nu)
        Q = np.diag(np.concatenate(var))
        S = C @ self.cov @ C.T + Q
        K = np.linalg.solve(S, C @ self.cov).T                          # Sigma C^T S^-1
        mu = self.mean + K @ nu
        mu[2] = wrap(mu[2])
        A = I3 - K @ C
        P = A @ self.cov @ A.T + K @ Q @ K.T                            # Joseph form
        self.mean = mu
        self.cov = 0.5 * (P + P.T)
