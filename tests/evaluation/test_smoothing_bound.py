"""The smoothing bound: the forward-backward form equals the inverse of the stacked
trajectory's Fisher information, lies below the filtering bound, and equals it at the end."""

from __future__ import annotations

import numpy as np

from beacon_sim.core.scenario import load_any_scenario
from beacon_sim.evaluation.pcrb import pcrb
from beacon_sim.evaluation.smoothing_bound import smoothing_bound, trajectory_information
from beacon_sim.runs.headless import run_headless


def _run(duration: float):
    sc = load_any_scenario("default").robots[0].scenario
    res = run_headless(sc, [], seed=3, duration=duration)
    truths = np.array([sc.initial_pose] + [st.true_pose for st in res.steps])
    controls = np.array([(st.control.v, st.control.omega) for st in res.steps])
    return sc, truths, controls


def test_forward_backward_bound_is_the_inverse_of_the_stacked_information():
    sc, truths, controls = _run(3.0)  # 60 ticks: J is 183 x 183
    P0 = np.diag([0.1, 0.1, 0.05]) ** 2
    J = trajectory_information(sc, truths, controls, P0)
    inv = np.linalg.inv(J)
    B = smoothing_bound(sc, truths[None], controls[None], P0)[0]
    for k in range(1, truths.shape[0]):
        np.testing.assert_allclose(B[k - 1], inv[3 * k:3 * k + 3, 3 * k:3 * k + 3], rtol=1e-6, atol=1e-14)


def test_smoothing_bound_is_below_the_filtering_bound_and_meets_it_at_the_end():
    sc, truths, controls = _run(30.0)
    Pf = pcrb(sc, truths[None], controls[None])[0]
    Ps = smoothing_bound(sc, truths[None], controls[None])[0]
    gap = np.linalg.eigvalsh(Pf - Ps)
    assert (gap >= -1e-10 * np.trace(Pf, axis1=1, axis2=2)[:, None]).all()
    np.testing.assert_allclose(Ps[-1], Pf[-1])
    mid = Pf.shape[0] // 2
    assert np.trace(Ps[mid]) < 0.8 * np.trace(Pf[mid])
