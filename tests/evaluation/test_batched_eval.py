"""Filters batched across runs (each filter's ``batched`` form, driven by
evaluation.montecarlo.batch_runs) give the per-run filters' estimates, covariances and NIS;
the truth stays that of ``Simulation(scenario, seed)``; a run's numbers do not depend on its
batch; ``eval`` prints the same table either way."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from beacon_sim.cli.main import main
from beacon_sim.core.motion import MotionNoise
from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.evaluation.metrics import nis
from beacon_sim.evaluation.montecarlo import batch_reason, batch_runs, run_monte_carlo
from beacon_sim.evaluation.report import table_lines
from beacon_sim.filters.gaussian import measurements as gm
from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter
from beacon_sim.filters.gaussian.measurements import SlotPacker, kalman_update
from beacon_sim.hosting.loading import build_filter

SEEDS = [2, 3, 11]
CASES = [  # scenario, duration [s], filters (with parameters)
    ("default", 25.0, [("ekf", {}), ("ekf", {"joseph": False}), ("ukf", {}), ("kf", {}),
                       ("dead_reckoning", {}), ("ukf", {"gate_chi2": 9.21})]),
    ("krejsa_bearing_only", 45.0, [("ekf", {}), ("ukf", {}), ("ukf", {"scaled": False, "kappa": 1.0}),
                                   ("dead_reckoning", {})]),
    ("assignment_kf", 40.0, [("kf", {}), ("ekf", {}), ("ukf", {"alpha": 0.5, "beta": 2.0})]),
]


@pytest.mark.parametrize("scenario, duration, filters", CASES, ids=[c[0] for c in CASES])
def test_batched_filters_equal_the_per_run_filters(scenario, duration, filters):
    """Every step: mean and covariance to 1e-9, and the joint NIS of the tick's readings
    against the predicted belief equal to metrics.nis (to 1e-9 relative)."""
    sc = load_scenario(scenario)
    sims = [Simulation(sc, s) for s in SEEDS]
    packer = SlotPacker(sc.world, sc.model_sensors)
    R = len(SEEDS)
    scalar = [[build_filter(spec, sc, s, params=p) for s in SEEDS] for spec, p in filters]
    assert all(fs[0].batch_blocker is None for fs in scalar)
    batched = [fs[0].batched(R) for fs in scalar]
    sensors = {s.name: s for s in sc.model_sensors}
    worst = 0.0
    kidnaps = 0
    for _ in range(round(duration / sc.dt)):
        steps = [sim.step() for sim in sims]
        kidnaps += sum(s.kidnapped for s in steps)
        v = np.array([s.control.v for s in steps])
        w = np.array([s.control.omega for s in steps])
        st = packer.pack([s.measurements for s in steps])
        for fs, fb in zip(scalar, batched, strict=True):
            fb.predict(v, w, sc.dt)
            for f, step in zip(fs, steps, strict=True):
                f.predict(step.control, step.dt)
            if st is not None:
                got = gm.nis(fb.mean, fb.cov, st)
                for i, (f, step) in enumerate(zip(fs, steps, strict=True)):
                    want, dof = nis(step.measurements, sensors, *f.estimate(), sc.world)
                    assert dof == np.count_nonzero(st.valid[i])
                    if step.measurements:
                        assert got[i] == pytest.approx(want, rel=1e-9, abs=1e-12)
                fb.update(st)
                if fb.own_nis:  # the EKF's update gives the same NIS
                    assert fb.last_nis == pytest.approx(got, rel=1e-9, abs=1e-12)
            for i, (f, step) in enumerate(zip(fs, steps, strict=True)):
                f.update(step.measurements)
                m, c = f.estimate()
                dm = np.abs(fb.mean[i] - m)
                dm[2] = min(dm[2], 2 * np.pi - dm[2])
                worst = max(worst, dm.max(), np.abs(fb.cov[i] - c).max())
    assert worst < 1e-9
    if scenario == "krejsa_bearing_only":
        assert kidnaps == R  # the kidnap happened inside the compared stretch


def test_kalman_update_is_the_textbook_kalman_update_for_one_run_and_for_runs():
    """Two range-bearing readings and a pose fix: x + K nu and the Joseph P against
    K = P H^T (H P H^T + R)^-1 written with an explicit inverse; the same function on one
    run (3,), (3, 3) and on runs (R, 3), (R, 3, 3) with empty slots."""
    rng = np.random.default_rng(4)
    A = rng.standard_normal((3, 3))
    P = A @ A.T * 0.01 + np.eye(3) * 1e-3
    mean = np.array([[2.0, 1.0, 0.3]])
    H = rng.standard_normal((1, 7, 3))
    H[0, 5:] = 0.0  # two empty slots
    nu = rng.standard_normal((1, 7)) * 0.1
    nu[0, 5:] = 0.0
    r = np.array([[0.01, 0.0025, 0.01, 0.0025, 0.02, 1.0, 1.0]])
    Hr, nur, Rr = H[0, :5], nu[0, :5], np.diag(r[0, :5])
    K = P @ Hr.T @ np.linalg.inv(Hr @ P @ Hr.T + Rr)
    want_m = mean[0] + K @ nur
    IKH = np.eye(3) - K @ Hr
    want_P = {True: IKH @ P @ IKH.T + K @ Rr @ K.T, False: P - K @ Hr @ P}
    want_nis = nur @ np.linalg.solve(Hr @ P @ Hr.T + Rr, nur)
    for joseph in (True, False):
        for m, Pn, nis_v in (kalman_update(mean, P[None], H, nu, r, joseph, want_nis=True, strict=False),
                             kalman_update(mean[0], P, Hr, nur, r[0, :5], joseph, want_nis=True)):
            assert np.allclose(m.reshape(3), want_m, atol=1e-12)
            assert np.allclose(Pn.reshape(3, 3), want_P[joseph], atol=1e-12)
            assert float(np.reshape(nis_v, -1)[0]) == pytest.approx(want_nis, rel=1e-10)


def test_linearise_matches_finite_differences():
    sc = load_scenario("default")
    sims = [Simulation(sc, s) for s in (1, 2)]
    packer = SlotPacker(sc.world, sc.model_sensors)
    st = None
    while st is None or np.count_nonzero(st.valid, axis=1).min() < 2:
        st = packer.pack([s.step().measurements for s in sims])
    mean = np.array([[2.4, 2.1, 0.2], [2.6, 2.3, -0.1]])
    H, nu, _ = st.linearise(mean)
    eps = 1e-6
    for j in range(3):
        d = np.zeros(3)
        d[j] = eps
        _, nu_p, _ = st.linearise(mean + d)
        _, nu_m, _ = st.linearise(mean - d)
        # nu = z - h, so dh/dx = -(nu(x + eps) - nu(x - eps)) / (2 eps)
        assert np.allclose(-(nu_p - nu_m) / (2 * eps), H[..., j], atol=1e-6)
    assert np.all(H[~st.valid] == 0) and np.all(nu[~st.valid] == 0)


def test_slots_are_fixed_by_the_sensors():
    """A reading's slot depends on its sensor and beacon only, never on the other runs."""
    sc = load_scenario("default")
    packer = SlotPacker(sc.world, sc.model_sensors)
    sims = [Simulation(sc, s) for s in (1, 2, 3)]
    for _ in range(30):
        ms = [s.step().measurements for s in sims]
        together = packer.pack(ms)
        for i, m in enumerate(ms):
            alone = packer.pack([m])
            if alone is None:
                assert together is None or not together.valid[i].any()
                continue
            assert np.array_equal(alone.valid[0], together.valid[i])
            assert np.array_equal(alone.z[0], together.z[i])
            assert np.array_equal(alone.r[0], together.r[i])


def test_truth_is_the_simulation_of_each_seed_and_runs_do_not_depend_on_their_batch():
    sc = load_scenario("krejsa_bearing_only")
    specs = ["ekf", "ukf", "dead_reckoning"]
    together = batch_runs(sc, specs, {}, [4, 5, 6], 35.0, [0, 1, 2])
    alone = batch_runs(sc, specs, {}, [5], 35.0, [1])
    for r, seed in zip(together, (4, 5, 6), strict=True):
        sim = Simulation(sc, seed)
        truth = [sim.pose.copy()] + [sim.step().true_pose for _ in range(350)]
        assert np.array_equal(r.truth, np.array(truth))
        assert r.truth_checksum == sim.truth_checksum
    for name in specs:
        a, b = together[1].filters[name], alone[0].filters[name]
        assert np.array_equal(a.err, b.err, equal_nan=True)
        assert np.array_equal(a.var, b.var, equal_nan=True)
        assert (a.nis_sum, a.nis_dof) == (b.nis_sum, b.nis_dof)


class _GatedLater(ExtendedKalmanFilter):
    """A subclass: its batched form is not the EKF's unless it says so itself."""


def test_batching_is_chosen_only_when_every_filter_has_a_batched_form():
    sc = load_scenario("default")
    assert batch_reason(sc, ["kf", "ekf", "ukf", "dead_reckoning"], {}) is None
    assert "pf" in batch_reason(sc, ["ekf", "pf"], {})
    # the EKF's and the UKF's gates are batched (tests/filters/test_outlier_gate.py)
    assert batch_reason(sc, ["ekf"], {"ekf": {"gate_chi2": 9.21}}) is None
    assert batch_reason(sc, ["ukf"], {"ukf": {"gate_chi2": 9.21}}) is None
    assert batch_reason(sc, ["ekf", "ukf"], {"ekf": {"joseph": False}, "ukf": {"scaled": False}}) is None
    assert "no batched form" in batch_reason(sc, [f"{__name__}:_GatedLater"], {})
    with pytest.raises(ValueError, match="cannot batch"):
        run_monte_carlo(sc, ["ekf", "histogram"], 1, duration=1.0, jobs=1, batch=True)
    # A gated UKF (on by default with declared outliers) gives the same runs batched and not.
    def outliers(sensors):
        return tuple(dataclasses.replace(s, outlier_rate=0.2) for s in sensors)

    noisy = dataclasses.replace(sc, sensors=outliers(sc.sensors), model_sensors=outliers(sc.model_sensors))
    assert batch_reason(noisy, ["ukf"], {}) is None
    runs = {b: run_monte_carlo(noisy, ["ukf"], 2, duration=10.0, jobs=1, batch=b) for b in (True, False)}
    for a, b in zip(runs[True], runs[False], strict=True):
        fa, fb = a.filters["ukf"], b.filters["ukf"]
        assert fa.steps == fb.steps == 200
        np.testing.assert_allclose(fa.err, fb.err, rtol=0, atol=1e-9)
        np.testing.assert_allclose(fa.var, fb.var, rtol=1e-9, atol=1e-12)


def test_each_filter_declares_what_its_batched_form_reproduces():
    """A parameter the class does not list in ``batch_params``, or a motion noise that is
    not a plain MotionNoise, keeps a filter to one run at a time."""
    sc = load_scenario("default")
    ekf = build_filter("ekf", sc, 0)
    assert ekf.batch_blocker is None
    ekf.params["new_option"] = 1
    assert "new_option" in ekf.batch_blocker

    class Noise(MotionNoise):
        pass

    sc2 = dataclasses.replace(sc, model_motion_noise=Noise(v_std=0.1))
    assert "MotionNoise" in build_filter("kf", sc2, 0).batch_blocker


def _eval(capsys, *extra):
    args = ["eval", "default", "krejsa_bearing_only", "--filter", "ekf", "--filter", "ukf",
            "--filter", "kf", "--filter", "dead_reckoning", "--runs", "4", "--duration", "40",
            "--seed", "7", "--json", *extra]
    assert main(args) == 0
    return json.loads(capsys.readouterr().out)


def _close(a, b, path=""):
    if isinstance(a, dict):
        assert a.keys() == b.keys(), path
        for k in a:
            if k not in ("us_per_step",):
                _close(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _close(x, y, f"{path}[{i}]")
    elif isinstance(a, float) and isinstance(b, float):
        assert a == pytest.approx(b, rel=1e-9, abs=1e-12), path
    else:
        assert a == b, path


def test_eval_gives_the_same_table_with_and_without_batching(capsys):
    batched = _eval(capsys, "--jobs", "2")
    per_run = _eval(capsys, "--jobs", "1", "--no-batch")
    for a, b in zip(batched["scenarios"], per_run["scenarios"], strict=True):
        assert table_lines(a, timing=False) == table_lines(b, timing=False)
        _close(a, b)
        for name in a["filters"]:  # every figure is there
            row = a["filters"][name]
            assert row["us_per_step"] > 0 and row["anis"] is not None
            assert row["pos_rmse_m"] is not None and row["anees"] is not None
        assert a["pcrb"]["pos_rmse_m"] > 0
    kidnap = batched["scenarios"][1]["filters"]["ekf"]["recovery"]
    assert kidnap and kidnap[0]["runs"] == 4
