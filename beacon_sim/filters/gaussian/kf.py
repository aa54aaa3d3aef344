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

The prediction is the EKF's code with A = I (``ekf.predict_moments``, on floats); the
update is ``measurements.kalman_update``, on one run here and on R runs at once in
:class:`BatchedKF`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

from beacon_sim.core.types import Measurement
from beacon_sim.filters.base import FilterContext
from beacon_sim.filters.gaussian.ekf import BatchedVelocityGaussian, VelocityGaussian
from beacon_sim.filters.gaussian.measurements import (
    FIX_KINDS,
    ReadingModels,
    StackedReadings,
    kalman_update,
    stack,
)


class KalmanFilter(VelocityGaussian):
    """Linear KF with A = I, B(theta), and C = I (pose fix) or [I2 0] (position fix)."""

    defaults: ClassVar[dict] = {}
    batch_params: ClassVar[dict[str, Any]] = {}
    sensor_kinds: ClassVar[tuple[str, ...]] = FIX_KINDS
    jacobian = False  # A = I

    def __init__(self, ctx: FilterContext):
        self.models = ReadingModels(ctx)
        super().__init__(ctx)

    def update(self, measurements: Sequence[Measurement]) -> None:
        st = stack(self.models, measurements, FIX_KINDS)  # bearings: not linear, ignored
        if st is None:
            return
        mean, cov = self.estimate()
        C, nu, q = st.linearise(mean)
        mu, P, _ = kalman_update(mean, cov, C, nu, q, joseph=True)
        self.x, self.y, self.th = mu.tolist()
        (p00, p01, p02), (_, p11, p12), (_, _, p22) = P.tolist()
        self.p = (p00, p01, p02, p11, p12, p22)

    def batched(self, runs: int) -> BatchedKF:
        mean, cov = self.estimate()
        return BatchedKF(mean, cov, runs, self.ctx.motion_noise)


class BatchedKF(BatchedVelocityGaussian):
    """:class:`KalmanFilter` for R runs: the same prediction on arrays, the same update on
    the fix slots of the tick's readings."""

    jacobian = False

    def update(self, st: StackedReadings) -> None:
        fixes = st.only(FIX_KINDS)
        if fixes is None:
            return
        C, nu, q = fixes.linearise(self.mean)
        self.mean, self.cov, _ = kalman_update(self.mean, self.cov, C, nu, q, joseph=True, strict=False)


__all__ = ["BatchedKF", "KalmanFilter"]
