"""An honest student whose EKF gates outlying readings (a chi-square gate of 9)."""

from typing import ClassVar

from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter


class MyEkf(ExtendedKalmanFilter):
    defaults: ClassVar[dict] = {**ExtendedKalmanFilter.defaults, "gate_chi2": 9.0}
