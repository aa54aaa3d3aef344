"""Consistency and behaviour of kf, ekf and ukf on whole simulated runs.

- ANEES over 50 seeded runs of a benign scenario inside the 95 % chi-square band;
- no beacon in view: the covariance grows every step;
- three beacons in view: the position standard deviation falls below a derived bound;
- seed 000's kidnap on krejsa_bearing_only: EKF and UKF reconverge.
"""

import itertools
import math
import tomllib

import numpy as np
import pytest

from beacon_sim.core import measurement_models as mm
from beacon_sim.core.metrics import anees_band, nees, pose_errors
from beacon_sim.core.resources import scenario_dir
from beacon_sim.core.scenario import parse_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.hosting.loading import build_filter
from beacon_sim.runs.headless import run_headless

BEACONS = [{"id": 1, "x": 2.0, "y": 2.0}, {"id": 2, "x": 8.0, "y": 2.0},
           {"id": 3, "x": 8.0, "y": 8.0}, {"id": 4, "x": 2.0, "y": 8.0}]


def benign(**over):
    """Four beacons always in view, every reading detected, no outliers, a circle of
    radius 3 m well inside the walls; filters are told the truth's noise (no [model])."""
    data = {
        "name": "benign", "dt": 0.1, "duration": 20.0,
        "world": {"bounds": [0.0, 0.0, 10.0, 10.0], "beacons": BEACONS},
        "robot": {"initial_pose": [5.0, 2.0, 0.0],
                  "motion_noise": {"v_std": 0.02, "v_frac": 0.05, "omega_std": 0.02,
                                   "omega_frac": 0.05}},
        "sensors": [
            {"name": "rb", "kind": "range_bearing", "period": 0.1, "range_std": 0.1,
             "bearing_std": 0.05},
            {"name": "fix", "kind": "pose", "period": 0.1, "position_std": 0.1,
             "heading_std": 0.05},
        ],
        "driver": {"kind": "constant", "v": 0.3, "omega": 0.1},
        "initial_belief": {"std": [0.05, 0.05, 0.02]},
    }
    data.update(over)
    return parse_scenario(data, "<benign>")


SAMPLE_STEPS = (50, 100, 150, 200)  # 5 s apart: the filters forget in well under a second
N_RUNS = 50


def _anees(sc, specs):
    """One NEES per sampled step per run: 50 runs x 4 steps = 200 nearly independent values."""
    values = {s: [] for s in specs}
    idx = [k - 1 for k in SAMPLE_STEPS]
    for seed in range(N_RUNS):
        r = run_headless(sc, list(specs), seed=seed)
        for name, tr in r.runner.tracks.items():
            assert not tr.failed, tr.failed
            e = pose_errors(np.array(tr.means)[idx], r.truth[idx])
            values[name].extend(nees(e, np.array(tr.covs)[idx]))
    return {k: float(np.mean(v)) for k, v in values.items()}


def test_anees_of_kf_ekf_ukf_inside_the_95_percent_band():
    """For an honest filter n * ANEES is chi-square with 3 n degrees of freedom (n = 200).

    ekf and ukf: the benign circle at 0.3 m/s. kf: seed 003's model has A = I, i.e. it drops
    the dependence of the position on the heading error (F's -v dt sin, v dt cos column), so
    it is only honest when that term vanishes: turning on the spot (v = 0), where its model
    is exact. On the moving circle it is overconfident (ANEES ~3.7, above the band): the
    price of A = I, shown in docs/filters.md.
    """
    lo, hi = anees_band(N_RUNS * len(SAMPLE_STEPS))
    moving = _anees(benign(), ["ekf", "ukf", "kf"])
    turning = _anees(benign(driver={"kind": "constant", "v": 0.0, "omega": 0.1}), ["kf"])
    print(f"band [{lo:.3f}, {hi:.3f}]; moving {moving}; kf turning on the spot {turning}")
    for name in ("ekf", "ukf"):
        assert lo <= moving[name] <= hi, (name, moving[name], lo, hi)
    assert lo <= turning["kf"] <= hi, ("kf", turning["kf"], lo, hi)
    assert moving["kf"] > hi  # A = I: overconfident when moving (documented limitation)


def _covariances(spec, sc, steps):
    f = build_filter(spec, sc, 0)
    out = []
    for st in steps:
        f.predict(st.control, st.dt)
        f.update(st.measurements)
        out.append(f.estimate()[1])
    return out


@pytest.mark.parametrize("spec", ["kf", "ekf", "ukf"])
def test_covariance_grows_every_step_with_no_beacon_in_view(spec):
    sc = benign(sensors=[
        {"name": "rb", "kind": "range_bearing", "max_range": 0.5},
        {"name": "fix", "kind": "pose", "max_range": 0.5}])
    steps = Simulation(sc, 0).run(10.0)
    assert not any(st.measurements for st in steps)
    covs = _covariances(spec, sc, steps)
    for a, b in itertools.pairwise(covs):
        assert np.linalg.det(b) > np.linalg.det(a)          # the uncertainty volume grows
        assert b[0, 0] + b[1, 1] > a[0, 0] + a[1, 1]        # and so does the position spread
        assert b[2, 2] > a[2, 2]


THREE = [{"id": 1, "x": 4.0, "y": 2.0}, {"id": 2, "x": 6.0, "y": 2.5}, {"id": 3, "x": 5.0, "y": 4.0}]


def test_kf_position_std_below_the_fix_bound_with_three_beacons():
    """Derivation. With three beacons in view the pose fix averages three independent
    per-beacon errors, so its noise is Q = diag(sp^2, sp^2, sth^2) / 3 (SensorSpec.fix_std).
    The KF posterior in information form is Sigma+^-1 = Sigma-^-1 + C^T Q^-1 C with C = I, and
    Sigma-^-1 is positive definite, so Sigma+^-1 > Q^-1, i.e. Sigma+ < Q: after every update
    the x and y standard deviations are below sp / sqrt(3) = 0.1 / sqrt(3) = 0.0577 m,
    whatever the prior (here 0.5 m)."""
    sc = benign(world={"bounds": [0.0, 0.0, 10.0, 10.0], "beacons": THREE},
                driver={"kind": "constant", "v": 0.0, "omega": 0.2},
                robot={"initial_pose": [5.0, 3.0, 0.0]},
                initial_belief={"std": [0.5, 0.5, 0.3]},
                sensors=[{"name": "fix", "kind": "pose", "max_range": 2.5, "position_std": 0.1,
                          "heading_std": 0.05, "period": 0.1}])
    steps = Simulation(sc, 0).run(3.0)
    assert all(len(st.measurements[0].beacon_ids) == 3 for st in steps)
    bound = 0.1 / math.sqrt(3)
    for cov in _covariances("kf", sc, steps):
        assert math.sqrt(cov[0, 0]) < bound and math.sqrt(cov[1, 1]) < bound


@pytest.mark.parametrize("spec", ["ekf", "ukf"])
def test_range_bearing_position_std_below_the_information_bound(spec):
    """Derivation. Three range-bearing readings carry the information
    J = sum_i H_i^T R^-1 H_i (H_i from the core's range_bearing_jacobian at the pose, R =
    diag(sr^2, sb^2)); J has full rank for three beacons not in a line. As above,
    P+^-1 = P-^-1 + J > J, so P+ < J^-1 and std(x) < sqrt((J^-1)_xx), likewise y. The filter
    linearises at its estimate, not the truth: allow 5 % for that. The bound holds for the
    EKF from the first update; the UKF's statistical linearisation adds the spread of h over
    its sigma points to S, which is large while the prior (0.5 m at 1.3 m range) is broad, so
    for the UKF it is checked from the second update on."""
    sc = benign(world={"bounds": [0.0, 0.0, 10.0, 10.0], "beacons": THREE},
                driver={"kind": "constant", "v": 0.0, "omega": 0.0},
                robot={"initial_pose": [5.0, 3.0, 0.0], "motion_noise": {"v_std": 0.01}},
                initial_belief={"std": [0.5, 0.5, 0.3]},
                sensors=[{"name": "rb", "kind": "range_bearing", "max_range": 2.5,
                          "range_std": 0.1, "bearing_std": 0.05}])
    steps = Simulation(sc, 0).run(3.0)
    assert all(len(st.measurements[0].beacon_ids) == 3 for st in steps)
    xy = np.array([[b["x"], b["y"]] for b in THREE])
    H = mm.range_bearing_jacobian(np.array([5.0, 3.0, 0.0]), xy)
    Rinv = np.diag([1 / 0.1**2, 1 / 0.05**2])
    J = sum(h.T @ Rinv @ h for h in H)
    bound = np.sqrt(np.diag(np.linalg.inv(J))[:2]) * 1.05
    assert bound.max() < 0.1  # the bound is a real constraint: far below the prior 0.5 m
    covs = _covariances(spec, sc, steps)
    for cov in covs[0 if spec == "ekf" else 1:]:
        assert np.all(np.sqrt(np.diag(cov)[:2]) < bound)


def _krejsa(model_noise=None):
    data = tomllib.loads((scenario_dir() / "krejsa_bearing_only.toml").read_text())
    # The filters are told the truth's noise, plus model_noise when given.
    data["model"] = {"motion_noise": model_noise or {}}
    return parse_scenario(data, "krejsa_bearing_only.toml", name="krejsa_bearing_only")


def _position_errors(result):
    out = {}
    for name, tr in result.runner.tracks.items():
        assert not tr.failed
        e = pose_errors(np.array(tr.means), result.truth[np.array(tr.ticks) - 1])
        out[name] = (np.hypot(e[:, 0], e[:, 1]), np.abs(e[:, 2]))
    return out


def test_seed_000_kidnap_ekf_and_ukf_reconverge():
    """Kidnap (+1 m, +0.5 m, -pi/2) at 30 s, seed 0. Told the truth's noise, both filters
    recover the heading within 15 s and their position error shrinks, but slowly (the
    belief was confident when the robot was moved): still ~1 m 30 s later. Telling the
    filters a larger process noise (pose_std 2 cm, 2 cm, 0.01 rad per step) makes them
    reconverge to the pre-kidnap accuracy within the 30 s, as the paper reports."""
    r = run_headless(_krejsa(), ["ekf", "ukf"], seed=0)
    for name, (pos, head) in _position_errors(r).items():
        assert pos[300] > 0.9, name                        # the kidnap moved the robot 1.1 m
        assert np.max(head[450:]) < 0.15, name             # heading back within 15 s
        assert pos[-1] < 0.75 * np.max(pos[300:]), name    # converging, slowly
    r = run_headless(_krejsa({"pose_std": [0.02, 0.02, 0.01]}), ["ekf", "ukf"], seed=0)
    for name, (pos, head) in _position_errors(r).items():
        assert np.mean(pos[-100:]) < 0.4, name             # reconverged
        assert np.max(head[450:]) < 0.15, name
