"""Attack (or a bug): ``os._exit(3)`` in the middle of a run. In a shared worker pool this
made an innocent classmate fail with "worker died (memory?)"."""

import os

from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter


class Quitter(ExtendedKalmanFilter):
    def reset(self, initial):
        super().reset(initial)
        self.t = 0.0

    def predict(self, control, dt):
        super().predict(control, dt)
        self.t += dt
        if self.t >= 1.0:
            os._exit(3)
