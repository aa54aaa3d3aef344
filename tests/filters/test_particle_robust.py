"""The particle filter on seeds nobody tuned to: it does not lose the robot on
``default``, and its covariance does not collapse after a kidnap."""

from __future__ import annotations

import numpy as np
import pytest

from beacon_sim.core.metrics import nees, pose_errors
from beacon_sim.core.scenario import load_scenario
from beacon_sim.evaluation.montecarlo import run_monte_carlo
from beacon_sim.evaluation.summary import Thresholds, evaluate
from beacon_sim.runs.headless import run_headless


def test_pf_keeps_the_robot_on_default_where_it_was_lost():
    # Seed 5001 lost it before (a 3.6 m excursion: PF 0.965 m against the EKF's 0.122 m,
    # random particles injected while tracking on a one-beacon ring): every run within
    # twice the EKF's error, and the set within 1.2x the bound.
    sc = load_scenario("default")
    runs = run_monte_carlo(sc, ["pf", "ekf"], 4, seed=5000, jobs=1)
    meta, _ = evaluate(sc, runs, Thresholds())
    pf, ekf = meta["filters"]["pf"], meta["filters"]["ekf"]
    for p, e in zip(pf["per_run"], ekf["per_run"], strict=True):
        assert p["pos_rmse_m"] <= 2.0 * e["pos_rmse_m"], (p["seed"], p["pos_rmse_m"], e["pos_rmse_m"])
    assert pf["rmse_over_pcrb"] <= 1.2
    assert pf["anees_verdict"] == "consistent"


def test_pf_covariance_admits_a_kidnap():
    # global_kidnap seed 2: at the second kidnap the weight fell on one particle and the
    # reported sigma was 0 while the error was 1.2 m (NEES 1.5e12). The belief must not be
    # that confident: NEES stays in the tens even in the steps right after a kidnap.
    sc = load_scenario("global_kidnap")
    r = run_headless(sc, ["pf"], seed=2)
    tr = r.runner.tracks["pf"]
    v = nees(pose_errors(np.array(tr.means), r.truth), np.array(tr.covs))
    times = sc.dt * np.arange(1, len(v) + 1)
    after = np.zeros(len(v), dtype=bool)
    for t in (30.0, 60.0):
        after |= (times >= t - 1e-9) & (times < t + 5.0)
    assert np.max(v[after]) < 100.0, float(np.max(v[after]))
    assert np.mean(v) < 6.0


@pytest.mark.parametrize("seed", [3, 11])
def test_pf_spread_never_collapses_after_a_kidnap(seed):
    # The symptom: 4 steps after a kidnap sigma 0.4 mm with a 3.85 m error. While
    # the error is over 1 m, the reported position sigma is at least a tenth of it, from
    # half a second after each kidnap (before that no reading may have told it yet).
    sc = load_scenario("global_kidnap")
    r = run_headless(sc, ["pf"], seed=seed)
    tr = r.runner.tracks["pf"]
    covs = np.array(tr.covs)
    err = pose_errors(np.array(tr.means), r.truth)
    pos = np.hypot(err[:, 0], err[:, 1])
    sigma = np.sqrt(covs[:, 0, 0] + covs[:, 1, 1])
    times = sc.dt * np.arange(1, len(pos) + 1)
    blind = np.zeros(len(pos), dtype=bool)
    for t in (30.0, 60.0):
        blind |= (times >= t - 1e-9) & (times < t + 0.5)
    big = (pos > 1.0) & ~blind
    assert big.any()
    assert np.all(sigma[big] >= 0.1 * pos[big]), float(np.min(sigma[big] / pos[big]))
