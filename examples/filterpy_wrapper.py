"""FilterpyEKF: filterpy's ``ExtendedKalmanFilter`` plugged into beacon-sim.

It shows that a filter you already wrote with another library plugs in by wrapping it in
the five methods of the interface. filterpy is optional (``pip install filterpy``, or
beacon-sim's ``bench`` extra); it is imported when the filter is built.

filterpy's EKF predicts the mean linearly (``x = F x + B u``), so the wrapper overrides
``predict_x`` with beacon-sim's velocity model; it updates with the measurement model, its
Jacobian, and a residual function that wraps bearing differences to [-pi, pi).

    beacon-sim run default --filter examples/filterpy_wrapper.py:FilterpyEKF --filter ekf
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from beacon_sim.api import (
    Control,
    FilterBase,
    FilterContext,
    FilterError,
    GaussianBelief,
    Measurement,
    broad_gaussian,
    motion,
    wrap,
)
from beacon_sim.api import (
    measurement_models as mm,
)


def _bearing_residual(z, h):
    """z - h with the bearing (second row of a [range, bearing] column) wrapped."""
    y = np.subtract(z, h)
    y[1::2] = wrap(y[1::2])
    return y


class FilterpyEKF(FilterBase):
    """filterpy's ExtendedKalmanFilter over ``[x, y, theta]`` (column state, shape (3, 1)).

    Handles range_bearing and bearing sensors (the kinds of seeds 000 and 001).
    """

    def __init__(self, ctx: FilterContext):
        super().__init__(ctx)
        try:
            from filterpy.kalman import ExtendedKalmanFilter
        except ImportError as exc:
            raise FilterError("FilterpyEKF needs filterpy: pip install filterpy") from exc
        for s in ctx.sensors:
            if s.kind not in ("range_bearing", "bearing"):
                raise FilterError(f"FilterpyEKF handles bearing and range_bearing sensors, "
                                  f"not {s.kind!r} ({s.name})")
        self.beacons = {b.id: np.array([b.x, b.y]) for b in ctx.world.beacons}
        self.kf = ExtendedKalmanFilter(dim_x=3, dim_z=2)
        self._control = Control()
        self._dt = ctx.dt
        # filterpy calls predict_x(u) then P = F P F^T + Q: give it the nonlinear model.
        self.kf.predict_x = self._predict_x

    def _predict_x(self, u=0) -> None:
        c = self._control
        self.kf.x = motion.move(self.kf.x[:, 0], c.v, c.omega, self._dt)[:, None]

    def reset(self, initial: GaussianBelief | None) -> None:
        initial = initial or broad_gaussian(self.ctx.world)
        self.kf.x = np.array(initial.mean, dtype=float).reshape(3, 1)
        self.kf.P = np.array(initial.cov, dtype=float)

    def predict(self, control: Control, dt: float) -> None:
        x = self.kf.x[:, 0]
        self._control, self._dt = control, dt
        self.kf.F = motion.jacobian_state(x, control.v, dt)
        self.kf.Q = self.ctx.motion_noise.process_cov(x, control.v, control.omega, dt)
        self.kf.predict()

    def update(self, measurements: Sequence[Measurement]) -> None:
        for m in measurements:
            if m.kind not in ("range_bearing", "bearing"):
                continue
            xy = np.array([self.beacons[int(i)] for i in m.beacon_ids])
            R = np.diag(np.tile(self.ctx.sensor(m.sensor).reading_std() ** 2, len(xy)))
            if m.kind == "range_bearing":
                self.kf.update(m.z.reshape(-1, 1), self._H_rb, self._h_rb, R=R, args=(xy,),
                               hx_args=(xy,), residual=_bearing_residual)
            else:
                self.kf.update(m.z.reshape(-1, 1), self._H_b, self._h_b, R=R, args=(xy,),
                               hx_args=(xy,), residual=lambda z, h: wrap(np.subtract(z, h)))
            self.kf.x[2, 0] = wrap(self.kf.x[2, 0])

    # filterpy passes the column state x (3, 1); stack all beacons of one reading.
    @staticmethod
    def _h_rb(x, xy):
        return mm.range_bearing(x[:, 0], xy).reshape(-1, 1)

    @staticmethod
    def _H_rb(x, xy):
        return mm.range_bearing_jacobian(x[:, 0], xy).reshape(-1, 3)

    @staticmethod
    def _h_b(x, xy):
        return mm.bearing(x[:, 0], xy).reshape(-1, 1)

    @staticmethod
    def _H_b(x, xy):
        return mm.bearing_jacobian(x[:, 0], xy)

    def estimate(self) -> tuple[np.ndarray, np.ndarray]:
        return self.kf.x[:, 0].copy(), np.array(self.kf.P, dtype=float)
