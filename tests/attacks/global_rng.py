"""A filter that adds noise from the global ``np.random`` generator (not ``ctx.rng``): a
different grade each time, unless the grader seeds the global generators."""

import numpy as np

from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter


class Noisy(ExtendedKalmanFilter):
    def estimate(self):
        mean, cov = super().estimate()
        return mean + np.random.normal(0.0, 0.001, 3) * np.array([1.0, 1.0, 0.0]), cov
