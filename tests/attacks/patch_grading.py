"""Attack: at import, wrap the grading module's run functions so that every other
student's error grows by 0.5 m (in a reused worker process this moved three honest
students from 0.25 m to 0.81 m)."""

import numpy as np

import beacon_sim.evaluation.grading as grading
import beacon_sim.evaluation.montecarlo as montecarlo
from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter


def _worse(run):
    for fr in run.filters.values():
        if "patch_grading" not in str(fr.failed):
            fr.err[:, :2] += 0.5
    return run


_one_run = grading.one_run
_isolated = montecarlo.isolated_run
grading.one_run = lambda *a, **k: _worse(_one_run(*a, **k))
montecarlo.isolated_run = grading.isolated_run = lambda *a, **k: (
    lambda out: (_worse(out[0]), out[1]))(_isolated(*a, **k))
np.seterr(all="ignore")


class Patcher(ExtendedKalmanFilter):
    pass
