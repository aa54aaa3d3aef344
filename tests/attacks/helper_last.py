"""A file whose filter class is followed by a helper class with an unrelated ``update``:
the helper must not be graded."""

from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter


class MyEkf(ExtendedKalmanFilter):
    pass


class Helper:
    """A running average: not a filter."""

    def __init__(self):
        self.n, self.total = 0, 0.0

    def update(self, value):
        self.n += 1
        self.total += value
