"""Attack: at import, wrap the grading modules' run functions so that every other
student's error grows by 0.5 m (in a reused worker process this moved three honest
students from 0.25 m to 0.81 m)."""

import numpy as np

import beacon_sim.evaluation.grading.students as students
import beacon_sim.evaluation.grading.tasks as tasks
import beacon_sim.evaluation.montecarlo.hosted as hosted
from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter


def _worse(run):
    for fr in run.filters.values():
        if "patch_grading" not in str(fr.failed):
            fr.err[:, :2] += 0.5
    return run


_one_run = tasks.one_run
_isolated = hosted.isolated_run
tasks.one_run = lambda *a, **k: _worse(_one_run(*a, **k))
hosted.isolated_run = students.isolated_run = lambda *a, **k: (
    lambda out: (_worse(out[0]), out[1]))(_isolated(*a, **k))
np.seterr(all="ignore")


class Patcher(ExtendedKalmanFilter):
    pass
