"""Attack: walk the interpreter's frames up to the runner and return its ``step.true_pose``
(plus 1 cm of noise) as the estimate. In the grader's own process this ranked first."""

import inspect

import numpy as np

from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter


class Cheat(ExtendedKalmanFilter):
    def estimate(self):
        mean, cov = super().estimate()
        for info in inspect.stack(0):
            step = info.frame.f_locals.get("step")
            pose = getattr(step, "true_pose", None)
            if pose is not None:
                return np.asarray(pose, dtype=float) + 0.01, cov
        return mean, cov
