"""MySlam: my own landmark SLAM filter for beacon-sim (docs/slam.md).

It runs as it is: it predicts with the motion model and puts every beacon it sees for the
first time on its map, but never corrects anything with a second reading, so the pose
drifts as dead reckoning does and each landmark stays where it was first seen. Fill in the
TODO to turn it into EKF-SLAM.

Try it (from the folder this file is in):

    beacon-sim check ./my_slam.py:MySlam
    beacon-sim play slam_loop --filter ./my_slam.py:MySlam --filter ekf_slam

On slam_loop the filter is not given the beacon map (ctx.map_known is False, and
ctx.world.beacons holds only the anchors, here none): it must map the beacons itself. The
window draws each landmark's 95 % ellipse from landmarks().

State s = [x, y, theta, m1x, m1y, m2x, m2y, ...] [m, m, rad, m, m, ...], covariance P.
Conventions: world frame, y up, theta counter-clockwise; every angle and angle DIFFERENCE
wrapped to [-pi, pi) with wrap().
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

import numpy as np

from beacon_sim.api import (
    Control,
    FilterBase,
    FilterContext,
    GaussianBelief,
    LandmarkMap,
    Measurement,
    broad_gaussian,
    motion,
    wrap,
)


class MySlam(FilterBase):
    """EKF-SLAM with known correspondence (each reading names its beacon), range-bearing."""

    defaults: ClassVar[dict] = {}
    sensor_kinds: ClassVar[tuple[str, ...]] = ("range_bearing",)

    def __init__(self, ctx: FilterContext):
        super().__init__(ctx)
        self.anchors = {b.id: (b.x, b.y) for b in ctx.world.beacons}  # beacons it is given
        self.reset(None)

    def reset(self, initial: GaussianBelief | None) -> None:
        initial = initial or broad_gaussian(self.ctx.world)
        self.s = np.array(initial.mean, dtype=float)
        self.P = np.array(initial.cov, dtype=float)
        self.ids: list[int] = []  # the beacon ID of each landmark, in state order

    def predict(self, control: Control, dt: float) -> None:
        """Only the pose moves: P_xx = F P_xx F^T + Q, P_xm = F P_xm."""
        pose = self.s[:3]
        F = motion.jacobian_state(pose, control.v, dt)
        Q = self.ctx.motion_noise.process_cov(pose, control.v, control.omega, dt)
        self.s[:3] = motion.move(pose, control.v, control.omega, dt)
        self.P[:3, :] = F @ self.P[:3, :]
        self.P[:, :3] = self.P[:, :3] @ F.T
        self.P[:3, :3] += Q

    def update(self, measurements: Sequence[Measurement]) -> None:
        for m in measurements:
            if m.kind != "range_bearing":
                continue
            R = np.diag(self.ctx.sensor(m.sensor).reading_std() ** 2)
            for z, beacon_id in zip(m.z, m.beacon_ids, strict=True):
                beacon_id = int(beacon_id)
                if beacon_id in self.anchors:
                    continue  # (an anchor's reading could correct the pose too: H has no m part)
                if beacon_id not in self.ids:
                    self._add(z, R, beacon_id)
                    continue
                j = 3 + 2 * self.ids.index(beacon_id)  # the landmark's first state index
                dx, dy = self.s[j] - self.s[0], self.s[j + 1] - self.s[1]
                q = dx * dx + dy * dy
                r = np.sqrt(q)
                h = np.array([r, wrap(np.arctan2(dy, dx) - self.s[2])])   # expected z
                H = np.zeros((2, self.s.size))   # dh/ds: non-zero for the pose and landmark j
                H[:, :3] = [[-dx / r, -dy / r, 0.0], [dy / q, -dx / q, -1.0]]
                H[:, j:j + 2] = [[dx / r, dy / r], [-dy / q, dx / q]]
                y = z - h
                y[1] = wrap(y[1])                # an angle difference: always wrap it
                self._correct(y, H, R)

    def _correct(self, y: np.ndarray, H: np.ndarray, R: np.ndarray) -> None:
        """One Kalman correction of the whole state: innovation y (2,), H (2, n), R (2, 2).

        TODO: it does nothing yet. Write:
            S = H P H^T + R
            K = P H^T S^-1                   (np.linalg.solve(S, H @ P).T)
            s <- s + K y, then wrap s[2]
            P <- P - K S K^T, then symmetrise: P <- (P + P^T) / 2
        """

    def _add(self, z: np.ndarray, R: np.ndarray, beacon_id: int) -> None:
        """A new landmark m = g(pose, z) = (x + r cos(theta + b), y + r sin(theta + b)), with
        P_mm = Gx P_xx Gx^T + Gz R Gz^T and its cross terms P_m* = Gx P_x*."""
        x, y, th = self.s[:3]
        r, b = z
        c, s_ = np.cos(th + b), np.sin(th + b)
        Gx = np.array([[1.0, 0.0, -r * s_], [0.0, 1.0, r * c]])   # dg/d(x, y, theta)
        Gz = np.array([[c, -r * s_], [s_, r * c]])                 # dg/d(r, b)
        n = self.s.size
        P = np.zeros((n + 2, n + 2))
        P[:n, :n] = self.P
        P[n:, :n] = Gx @ self.P[:3, :]
        P[:n, n:] = P[n:, :n].T
        P[n:, n:] = Gx @ self.P[:3, :3] @ Gx.T + Gz @ R @ Gz.T
        self.s = np.concatenate([self.s, [x + r * c, y + r * s_]])
        self.P = P
        self.ids.append(beacon_id)

    def estimate(self) -> tuple[np.ndarray, np.ndarray]:
        """The pose's mean (3,) and covariance (3, 3); copies."""
        return self.s[:3].copy(), self.P[:3, :3].copy()

    def landmarks(self) -> LandmarkMap:
        """The map: each landmark's beacon ID, mean (M, 2) [m] and covariance (M, 2, 2)."""
        M = len(self.ids)
        covs = np.array([self.P[3 + 2 * k:5 + 2 * k, 3 + 2 * k:5 + 2 * k] for k in range(M)])
        return LandmarkMap(np.array(self.ids, dtype=int), self.s[3:].reshape(M, 2).copy(),
                           covs.reshape(M, 2, 2))
