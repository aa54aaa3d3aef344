"""An honest student whose EKF gates outlying readings (a chi-square gate of 9)."""

from beacon_sim.filters.ekf import ExtendedKalmanFilter


class MyEkf(ExtendedKalmanFilter):
    defaults = {**ExtendedKalmanFilter.defaults, "gate_chi2": 9.0}
