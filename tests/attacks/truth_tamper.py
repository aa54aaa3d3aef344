"""Attack: find the grader's truth array (the float (T + 1, 3) arrays in memory) and write
the filter's own mean into it, so that its error is zero."""

import gc

import numpy as np

from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter


class Cheat(ExtendedKalmanFilter):
    def reset(self, initial):
        super().reset(initial)
        self.k = 0
        self.truths = [o for o in gc.get_objects() if isinstance(o, np.ndarray) and o.ndim == 2
                       and o.shape[1] == 3 and o.shape[0] > 50 and o.dtype == float]

    def estimate(self):
        mean, cov = super().estimate()
        self.k += 1
        for t in self.truths:
            if self.k < t.shape[0]:
                t[self.k] = mean
        return mean, cov
