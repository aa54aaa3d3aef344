"""Dead reckoning: prediction only, the baseline every comparison shows.

The mean follows the velocity model with the command; the covariance grows as the EKF's
prediction would (``F P F^T + Q``), so its ellipse shows how fast odometry alone drifts.

One run: written with the core's numpy model functions, as the filter template
(``filters/template.py``) writes it, which must stay bit for bit this filter. R runs at once:
the EKF's prediction on arrays (``ekf.BatchedVelocityGaussian``), the same maths.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np

from beacon_sim.core import motion
from beacon_sim.core.types import Control, Measurement
from beacon_sim.filters.base import FilterContext, GaussianBelief, broad_gaussian
from beacon_sim.filters.ekf import BatchedVelocityGaussian
from beacon_sim.filters.gaussian_measurements import BatchableFilter


class DeadReckoning(BatchableFilter):
    """Integrates the commands; ignores every measurement."""

    batch_params: ClassVar[dict[str, Any]] = {}

    def __init__(self, ctx: FilterContext):
        super().__init__(ctx)
        self.mean = np.zeros(3)
        self.cov = np.eye(3)

    def reset(self, initial: GaussianBelief | None) -> None:
        initial = initial or broad_gaussian(self.ctx.world)
        self.mean = np.array(initial.mean, dtype=float)
        self.cov = np.array(initial.cov, dtype=float)

    def predict(self, control: Control, dt: float) -> None:
        F = motion.jacobian_state(self.mean, control.v, dt)
        Q = self.ctx.motion_noise.process_cov(self.mean, control.v, control.omega, dt)
        self.mean = motion.move(self.mean, control.v, control.omega, dt)
        self.cov = F @ self.cov @ F.T + Q

    def update(self, measurements: Sequence[Measurement]) -> None:
        """Dead reckoning uses no measurement."""

    def estimate(self) -> tuple[np.ndarray, np.ndarray]:
        return self.mean.copy(), self.cov.copy()

    def batched(self, runs: int) -> BatchedDeadReckoning:
        return BatchedDeadReckoning(self.mean, self.cov, runs, self.ctx.motion_noise)


class BatchedDeadReckoning(BatchedVelocityGaussian):
    """:class:`DeadReckoning` for R runs: the EKF's prediction on arrays, no update."""
