"""Attack: find the ``Simulation`` object through ``gc.get_objects()`` and return its true
pose as the estimate."""

import gc

import numpy as np

from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter


class Cheat(ExtendedKalmanFilter):
    def _sim(self):
        for obj in gc.get_objects():
            if type(obj).__name__ == "Simulation" and hasattr(obj, "pose"):
                return obj
        return None

    def reset(self, initial):
        super().reset(initial)
        self.sim = self._sim()

    def estimate(self):
        mean, cov = super().estimate()
        if self.sim is not None:
            return np.array(self.sim.pose, dtype=float), cov
        return mean, cov
