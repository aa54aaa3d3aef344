"""MyFilter: my own localisation filter for beacon-sim.

It runs as it is: it is dead reckoning (it predicts with the motion model and ignores the
measurements). Fill in the TODOs to turn it into an extended Kalman filter; the finished
version is in beacon-sim's examples/student_ekf.py and the tutorial in
docs/writing-a-filter.md.

Try it (from the folder this file is in):

    beacon-sim check my_filter.py:MyFilter              # does it follow the interface?
    beacon-sim play --filter ./my_filter.py:MyFilter --filter ekf   # live, beside the EKF
    beacon-sim run default --filter ./my_filter.py:MyFilter --filter ekf
    beacon-sim eval default --filter ./my_filter.py:MyFilter --filter ekf --runs 20

In the window, saving this file reloads the filter (it restarts from the initial belief);
if the file has an error, the message shows on screen and the previous version keeps running.

Conventions: the pose is [x, y, theta] in metres, metres, radians, world frame (y up,
theta counter-clockwise from +x). Every angle and every angle DIFFERENCE must be wrapped
to [-pi, pi) with beacon_sim.core.angles.wrap.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

import numpy as np

# The models and Jacobians the simulator itself uses (all tested against finite differences):
#   motion.move(pose, v, omega, dt)              -> next pose, heading wrapped
#   motion.jacobian_state(pose, v, dt)           -> F = d move / d pose, (3, 3)
#   motion.jacobian_control(pose, dt)            -> B = d move / d (v, omega), (3, 2)
#   ctx.motion_noise.process_cov(pose, v, omega, dt) -> Q = B M B^T (+ pose noise), (3, 3)
#   mm.bearing(pose, beacon_xy)                  -> bearings [rad], (m,)
#   mm.bearing_jacobian(pose, beacon_xy)         -> H, (m, 3)
#   mm.range_bearing(pose, beacon_xy)            -> [range, bearing] rows, (m, 2)
#   mm.range_bearing_jacobian(pose, beacon_xy)   -> one H block per beacon, (m, 2, 3)
#   mm.pose_fix(pose) / mm.position_fix(pose)    -> h for pose / position fixes
#                                                   (H = identity / mm.POSITION_H)
#   mm.bearing_many / mm.range_many              -> the same for N poses (particle filters)
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


class MyFilter(FilterBase):
    """A Gaussian filter over the pose.

    ``self.ctx`` holds everything the filter may know: ``ctx.world.beacons`` (id, x, y),
    ``ctx.motion_noise``, ``ctx.sensor(name)`` (a sensor's kind and the noise the filter is
    told: ``reading_std()``, ``fix_std(n_beacons, hdop)``), ``ctx.params`` and ``ctx.rng``,
    the only random generator you may use. It never holds the true pose.
    """

    # Parameters you can set from a scenario's [filters.MyFilter] table or with
    # --set MyFilter.KEY=VALUE; unknown names are an error.
    defaults: ClassVar[dict] = {"use_measurements": True}

    def __init__(self, ctx: FilterContext):
        super().__init__(ctx)   # stores self.ctx and self.params
        # beacon id -> (x, y) [m]: each reading names its beacon (known correspondence)
        self.beacons = {b.id: (b.x, b.y) for b in ctx.world.beacons}
        self.mean = np.zeros(3)
        self.cov = np.eye(3)

    def reset(self, initial: GaussianBelief | None) -> None:
        """Start from a Gaussian belief (None asks for a uniform one: use a broad Gaussian)."""
        initial = initial or broad_gaussian(self.ctx.world)
        self.mean = np.array(initial.mean, dtype=float)
        self.cov = np.array(initial.cov, dtype=float)

    def predict(self, control: Control, dt: float) -> None:
        """Motion update with the command (control.v [m/s], control.omega [rad/s]) over dt [s]."""
        F = motion.jacobian_state(self.mean, control.v, dt)
        Q = self.ctx.motion_noise.process_cov(self.mean, control.v, control.omega, dt)
        self.mean = motion.move(self.mean, control.v, control.omega, dt)   # mean' = g(mean, u)
        self.cov = F @ self.cov @ F.T + Q                                  # P' = F P F^T + Q

    def update(self, measurements: Sequence[Measurement]) -> None:
        """Measurement update. The list is often empty; each item is one sensor's readings:
        m.sensor (its name), m.kind, m.z (one row per reading) and m.beacon_ids."""
        if not self.params["use_measurements"]:
            return
        for m in measurements:
            if m.kind == "range_bearing":
                for z, beacon_id in zip(m.z, m.beacon_ids, strict=True):
                    if beacon_id < 0:  # no ID (correspondence = "unknown"): writing-a-filter.md 8c
                        continue
                    beacon_xy = self.beacons.get(int(beacon_id))
                    if beacon_xy is None:  # not on the map it was given (SLAM: new-filter --slam)
                        continue
                    h = mm.range_bearing(self.mean, beacon_xy)[0]             # expected z, (2,)
                    H = mm.range_bearing_jacobian(self.mean, beacon_xy)[0]    # (2, 3)
                    y = z - h                                                 # innovation
                    y[1] = wrap(y[1])                  # an angle difference: always wrap it
                    R = np.diag(self.ctx.sensor(m.sensor).reading_std() ** 2)
                    self._correct(y, H, R)
            # TODO 2: the other kinds, when your scenario has them:
            #   "bearing":  h = mm.bearing(...), H = mm.bearing_jacobian(...), wrap y
            #   "pose":     h = mm.pose_fix(self.mean), H = np.eye(3), wrap y[2],
            #               R = diag(self.ctx.sensor(m.sensor).fix_std(len(m.beacon_ids)) ** 2)
            #   "position": h = mm.position_fix(self.mean), H = mm.POSITION_H,
            #               R = diag(spec.fix_std(len(m.beacon_ids), m.hdop) ** 2)

    def _correct(self, y: np.ndarray, H: np.ndarray, R: np.ndarray) -> None:
        """One Kalman correction: innovation y (m,), Jacobian H (m, 3), noise covariance R (m, m).

        TODO 1: it does nothing yet, so the filter is still dead reckoning. Write:
            S = H P H^T + R                 (innovation covariance)
            K = P H^T S^-1                  (np.linalg.solve(S, H @ P).T, no inverse needed)
            mean <- mean + K y, then wrap mean[2]
            cov  <- (I - K H) P (I - K H)^T + K R K^T     (Joseph form: stays symmetric PSD)
        """

    def estimate(self) -> tuple[np.ndarray, np.ndarray]:
        """The mean (3,) [m, m, rad] and covariance (3, 3); return copies."""
        return self.mean.copy(), self.cov.copy()
