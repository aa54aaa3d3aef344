"""Dead reckoning: prediction only, the baseline every comparison shows.

The mean follows the velocity model with the command; the covariance grows as the EKF's
prediction would (``F P F^T + Q``), so its ellipse shows how fast odometry alone drifts.

One run: written with the core's numpy model functions, as the filter template
(``templates/my_filter.py``) writes it, which must stay bit for bit this filter. R
runs at once: the EKF's prediction on arrays (``ekf.BatchedVelocityGaussian``), the same maths.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np

from beacon_sim.core import motion
from beacon_sim.core.angles import wrap
from beacon_sim.core.types import Control, Measurement
from beacon_sim.filters.base import FilterContext, GaussianBelief, broad_gaussian
from beacon_sim.filters.gaussian.ekf import BatchedVelocityGaussian
from beacon_sim.filters.gaussian.measurements import BatchableFilter


class DeadReckoning(BatchableFilter):
    """Integrates the commands; ignores every measurement."""

    batch_params: ClassVar[dict[str, Any]] = {}

    def __init__(self, ctx: FilterContext):
        super().__init__(ctx)
        self.mean = np.zeros(3)
        self.cov = np.eye(3)
        self._pose_var: tuple[float, np.ndarray] | None = None   # (slip gain, diag(pose_std^2))

    def reset(self, initial: GaussianBelief | None) -> None:
        initial = initial or broad_gaussian(self.ctx.world)
        self.mean = np.array(initial.mean, dtype=float)
        self.cov = np.array(initial.cov, dtype=float)

    def predict(self, control: Control, dt: float) -> None:
        noise = self.ctx.motion_noise
        if type(noise) is not motion.MotionNoise:   # someone's own noise model: as it says
            F = motion.jacobian_state(self.mean, control.v, dt)
            Q = noise.process_cov(self.mean, control.v, control.omega, dt)
            self.mean = motion.move(self.mean, control.v, control.omega, dt)
            self.cov = F @ self.cov @ F.T + Q
            return
        # The same operations as jacobian_state, process_cov and move (so the bits of the
        # template's filter), with the heading's cos and sin taken once and diag(pose_std^2)
        # built once per slip gain (slip scales with the command: MotionNoise.slip_gain).
        v, w = control.v, control.omega
        m = self.mean
        th = m[2]
        c, s = np.cos(float(th)), np.sin(float(th))
        F = np.array([[1.0, 0.0, -v * dt * s], [0.0, 1.0, v * dt * c], [0.0, 0.0, 1.0]])
        B = np.array([[dt * c, 0.0], [dt * s, 0.0], [0.0, dt]])
        g = noise.slip_gain(v, w)
        if self._pose_var is None or self._pose_var[0] != g:
            self._pose_var = (g, np.diag(np.square(noise.pose_std_at(v, w))))
        Q = B @ noise.control_cov(v, w) @ B.T + self._pose_var[1]
        mean = np.empty(3)
        mean[0] = m[0] + v * dt * c
        mean[1] = m[1] + v * dt * s
        mean[2] = wrap(th + w * dt)
        self.mean = mean
        self.cov = F @ self.cov @ F.T + Q

    def update(self, measurements: Sequence[Measurement]) -> None:
        """Dead reckoning uses no measurement."""

    def estimate(self) -> tuple[np.ndarray, np.ndarray]:
        return self.mean.copy(), self.cov.copy()

    def batched(self, runs: int) -> BatchedDeadReckoning:
        return BatchedDeadReckoning(self.mean, self.cov, runs, self.ctx.motion_noise)


class BatchedDeadReckoning(BatchedVelocityGaussian):
    """:class:`DeadReckoning` for R runs: the EKF's prediction on arrays, no update."""


__all__ = ["BatchedDeadReckoning", "DeadReckoning"]
