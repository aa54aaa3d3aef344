"""MyTdoa: an extended Kalman filter on range differences (TDOA) for beacon-sim.

It runs as it is, on the ``ruiz_ulps`` and ``ulps_leave`` scenarios (docs/distance_beacons.md):
ceiling beacons emit together, the robot times each arrival and keeps the differences of the
distances against a reference beacon. As written it makes the mistake common firmware makes:
it takes the differences as independent, each with variance 2 sigma^2. TODO 1 asks for their
true covariance; then compare the two (the filter's per-axis NEES, docs/distance_beacons.md).

Try it (from the folder this file is in):

    beacon-sim check my_tdoa.py:MyTdoa --scenario ruiz_ulps
    beacon-sim play ulps_leave --filter ./my_tdoa.py:MyTdoa --filter ekf
    beacon-sim eval ulps_leave --filter ./my_tdoa.py:MyTdoa --filter ekf --runs 20

A ``tdoa`` reading: ``m.z`` (k, 1), row i the difference ``r_i - r_ref`` [m];
``m.beacon_ids`` (k + 1,): the reference first, then the beacon of each row. The beacons are
``spec.beacon_height`` metres above the robot (its height is known), so the distance from the
pose (x, y) to a beacon at (bx, by) is ``r = sqrt((x - bx)^2 + (y - by)^2 + h^2)``.
Conventions: the pose is [x, y, theta] in metres, metres, radians, world frame.
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


class MyTdoa(FilterBase):
    """A Gaussian filter over the pose that updates on range differences."""

    def __init__(self, ctx: FilterContext):
        super().__init__(ctx)
        # beacon id -> (x, y) [m]
        self.beacons = {b.id: (b.x, b.y) for b in ctx.world.beacons}
        self.mean = np.zeros(3)
        self.cov = np.eye(3)

    def reset(self, initial: GaussianBelief | None) -> None:
        initial = initial or broad_gaussian(self.ctx.world)
        self.mean = np.array(initial.mean, dtype=float)
        self.cov = np.array(initial.cov, dtype=float)

    def predict(self, control: Control, dt: float) -> None:
        F = motion.jacobian_state(self.mean, control.v, dt)
        Q = self.ctx.motion_noise.process_cov(self.mean, control.v, control.omega, dt)
        self.mean = motion.move(self.mean, control.v, control.omega, dt)   # mean' = g(mean, u)
        self.cov = F @ self.cov @ F.T + Q                                  # P' = F P F^T + Q

    def update(self, measurements: Sequence[Measurement]) -> None:
        for m in measurements:
            if m.kind != "tdoa" or len(m) == 0:
                continue
            spec = self.ctx.sensor(m.sensor)
            h2 = spec.beacon_height ** 2
            bxy = np.array([self.beacons[int(i)] for i in m.beacon_ids])   # reference first
            d = self.mean[:2] - bxy                                       # (k + 1, 2)
            r = np.sqrt(np.sum(d * d, axis=1) + h2)                       # distances [m]
            u = d / r[:, None]                                            # d r / d (x, y)
            h = r[1:] - r[0]                                              # expected differences
            H = np.zeros((len(m), 3))
            H[:, :2] = u[1:] - u[0]                                       # d h / d pose
            y = np.asarray(m.z, dtype=float)[:, 0] - h                    # innovation
            s = spec.noise.range_std                                      # one arrival's noise
            k = len(m)
            R = 2.0 * s * s * np.eye(k)
            # TODO 1: every difference carries the reference's arrival error, so the rows are
            # correlated: cov(d_i, d_j) = s^2 for i != j, var(d_i) = 2 s^2. Replace R with
            #     R = s^2 (I + 1 1^T)        (s * s * (np.eye(k) + np.ones((k, k))))
            # and compare the two with `beacon-sim eval ulps_leave`: the ANEES barely moves,
            # the per-axis NEES does (docs/distance_beacons.md, "The lesson, as measured").
            self._correct(y, H, R)

    def _correct(self, y: np.ndarray, H: np.ndarray, R: np.ndarray) -> None:
        """The Kalman correction with a full R (Joseph form)."""
        P = self.cov
        S = H @ P @ H.T + R                                   # innovation covariance
        K = np.linalg.solve(S, H @ P).T                       # K = P H^T S^-1
        self.mean = self.mean + K @ y
        self.mean[2] = wrap(self.mean[2])
        A = np.eye(3) - K @ H
        self.cov = A @ P @ A.T + K @ R @ K.T

    def estimate(self) -> tuple[np.ndarray, np.ndarray]:
        return self.mean.copy(), self.cov.copy()
