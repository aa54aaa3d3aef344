"""The smoothers against the maths: RTS on a linear-Gaussian model is the batch
least-squares (information-form) posterior; a smoothed covariance is never above the
filtered one; recording the moments leaves a filter's results bit for bit; the fixed-lag
smoother is the fixed-interval one over its window; seeded Monte Carlo: the smoother beats
the filter and its covariance is honest."""

from __future__ import annotations

import numpy as np
import pytest

from beacon_sim.core.scenario import load_any_scenario
from beacon_sim.core.types import Control
from beacon_sim.evaluation.smoothing_run import smoothing_monte_carlo
from beacon_sim.filters.smoothing import FixedLagSmoother, MomentRecorder, rts_smooth, velocity_jacobian
from beacon_sim.hosting.loading import build_filter
from beacon_sim.runs.headless import run_headless
from beacon_sim.runs.smoothing import NotSmoothable, smooth_steps, smoothable


def _default():
    return load_any_scenario("default").robots[0].scenario


def _kalman(m0, P0, Fs, Qs, Hs, Rs, zs):
    """A textbook linear Kalman filter: (filtered means, covs, predicted means, covs)."""
    m, P = m0.copy(), P0.copy()
    fm, fc, pm, pc = [m], [P], [], []
    for F, Q, H, R, z in zip(Fs, Qs, Hs, Rs, zs, strict=True):
        m, P = F @ m, F @ P @ F.T + Q
        pm.append(m)
        pc.append(P)
        S = H @ P @ H.T + R
        K = P @ H.T @ np.linalg.inv(S)
        m = m + K @ (z - H @ m)
        P = (np.eye(len(m)) - K @ H) @ P
        fm.append(m)
        fc.append(P)
    return np.array(fm), np.array(fc), np.array(pm), np.array(pc)


def test_rts_on_a_linear_gaussian_model_is_the_batch_least_squares_posterior():
    rng = np.random.default_rng(4)
    n, T = 3, 12
    m0 = rng.normal(size=n)
    P0 = np.diag(rng.uniform(0.5, 2.0, n))
    Fs = [np.eye(n) + 0.3 * rng.normal(size=(n, n)) for _ in range(T)]
    Qs = [np.diag(rng.uniform(0.01, 0.2, n)) for _ in range(T)]
    Hs = [rng.normal(size=(2, n)) for _ in range(T)]
    Rs = [np.diag(rng.uniform(0.05, 0.5, 2)) for _ in range(T)]
    zs = [rng.normal(size=2) for _ in range(T)]
    fm, fc, pm, pc = _kalman(m0, P0, Fs, Qs, Hs, Rs, zs)
    sm, sc = rts_smooth(fm, fc, pm, pc, np.array(Fs), angles=())
    # The stacked trajectory's information J and vector b: prior, motion and reading terms.
    N = n * (T + 1)
    J, b = np.zeros((N, N)), np.zeros(N)
    J[:n, :n] += np.linalg.inv(P0)
    b[:n] += np.linalg.inv(P0) @ m0
    for k in range(T):
        A = np.zeros((n, N))
        A[:, n * k:n * k + n] = -Fs[k]
        A[:, n * k + n:n * k + 2 * n] = np.eye(n)
        J += A.T @ np.linalg.inv(Qs[k]) @ A
        E = np.zeros((2, N))
        E[:, n * k + n:n * k + 2 * n] = Hs[k]
        J += E.T @ np.linalg.inv(Rs[k]) @ E
        b += E.T @ np.linalg.inv(Rs[k]) @ zs[k]
    cov = np.linalg.inv(J)
    mean = cov @ b
    np.testing.assert_allclose(sm.reshape(-1), mean, atol=1e-9)
    for k in range(T + 1):
        np.testing.assert_allclose(sc[k], cov[n * k:n * k + n, n * k:n * k + n], atol=1e-9)
    # the last tick is the filter's own; the first is not
    np.testing.assert_allclose(sm[-1], fm[-1])
    assert np.abs(sm[0] - fm[0]).max() > 1e-3


def test_velocity_jacobian_matches_finite_differences():
    x = np.array([1.0, 2.0, 2.5])
    v, w, dt, h = 0.7, 0.3, 0.1, 1e-6

    def f(p):
        return np.array([p[0] + v * dt * np.cos(p[2]), p[1] + v * dt * np.sin(p[2]), p[2] + w * dt])

    num = np.array([(f(x + h * e) - f(x - h * e)) / (2 * h) for e in np.eye(3)]).T
    np.testing.assert_allclose(velocity_jacobian(x, v, dt), num, atol=1e-8)


@pytest.fixture(scope="module")
def default_run():
    sc = _default()
    return sc, run_headless(sc, ["ekf", "ukf"], seed=7, duration=40.0)


@pytest.mark.parametrize("spec", ["ekf", "ukf"])
def test_recording_the_moments_leaves_the_filter_bit_for_bit(default_run, spec):
    sc, res = default_run
    tr = smooth_steps(sc, spec, 7, res.steps)
    ticks, means, covs = res.filters.series(spec)
    assert np.array_equal(tr.ticks[1:], ticks)
    assert np.array_equal(tr.filtered_means[1:], means[:, 0])
    assert np.array_equal(tr.filtered_covs[1:], covs[:, 0])


@pytest.mark.parametrize("spec", ["ekf", "ukf"])
def test_smoothed_covariance_is_never_above_the_filtered(default_run, spec):
    sc, res = default_run
    tr = smooth_steps(sc, spec, 7, res.steps)
    gap = np.linalg.eigvalsh(tr.filtered_covs - tr.smoothed_covs)  # P_f - P_s >= 0
    scale = np.trace(tr.filtered_covs, axis1=1, axis2=2)[:, None]
    assert (gap >= -1e-9 * scale).all()
    # and strictly smaller somewhere in the middle of the run (the future's readings help)
    mid = len(tr.ticks) // 2
    assert np.trace(tr.smoothed_covs[mid]) < 0.9 * np.trace(tr.filtered_covs[mid])
    np.testing.assert_array_equal(tr.smoothed_means[-1], tr.filtered_means[-1])
    assert (np.abs(tr.smoothed_means[:, 2]) <= np.pi).all()


def test_fixed_lag_smoother_is_the_fixed_interval_one_over_its_window(default_run):
    sc, res = default_run
    steps = res.steps[:300]
    lag = 40
    fl = FixedLagSmoother(build_filter("ekf", sc, 7), lag)
    lagged = {}
    for st in steps:
        fl.predict(st.control, st.dt)
        fl.update(st.measurements)
        tick, m, P = fl.lagged()
        lagged[tick] = (m, P)
    # at the last tick: tick T - lag, smoothed with the readings up to T
    full = smooth_steps(sc, "ekf", 7, steps)
    T = len(steps)
    m, P = lagged[T - lag]
    k = full.at(T - lag)
    np.testing.assert_allclose(m, full.smoothed_means[k], atol=1e-9)
    np.testing.assert_allclose(P, full.smoothed_covs[k], atol=1e-12)
    # an earlier tick: the interval smoother of the run cut where the lagged one stood
    cut = smooth_steps(sc, "ekf", 7, steps[:200])
    m, P = lagged[200 - lag]
    np.testing.assert_allclose(m, cut.smoothed_means[cut.at(200 - lag)], atol=1e-9)
    # the filter inside is untouched
    np.testing.assert_array_equal(fl.estimate()[0], full.filtered_means[-1])


def test_fixed_lag_rejects_a_bad_lag():
    with pytest.raises(ValueError, match="lag 0"):
        FixedLagSmoother(build_filter("ekf", _default(), 1), 0)


def test_only_gaussian_velocity_filters_are_smoothed(default_run):
    sc, res = default_run
    assert smoothable("ekf") and smoothable("ukf")
    assert not smoothable("pf") and not smoothable("no_such_filter")
    with pytest.raises(NotSmoothable, match="pf: no smoother"):
        smooth_steps(sc, "pf", 7, res.steps[:5])


def test_a_reset_starts_a_new_segment():
    sc = _default()
    rec = MomentRecorder(build_filter("ekf", sc, 1))
    for _ in range(3):
        rec.predict(Control(0.3, 0.1), sc.dt)
        rec.update([])
    rec.reset(None)
    rec.predict(Control(0.3, 0.1), sc.dt)
    assert len(rec.segments) == 2 and rec.segments[1].ticks == [3, 4]


def test_smoother_beats_the_filter_and_is_consistent_over_seeded_runs():
    """Seeded Monte Carlo (8 runs x 40 s of the classroom room): the smoothed position RMSE
    is below the filtered one, its ANEES is near 3 (3 dof), and it does not beat the
    smoothing bound by more than the spread of 8 runs allows."""
    sc = _default()
    f = smoothing_monte_carlo(sc, "ekf", range(500, 508), duration=40.0)
    s, fl = f["smoothed"], f["filtered"]
    assert s["pos_rmse_m"] < 0.85 * fl["pos_rmse_m"]
    assert 2.0 < s["anees"] < 4.5
    assert s["bound_pos_rmse_m"] < fl["bound_pos_rmse_m"]
    assert s["pos_rmse_over_bound"] > 0.8
    # errors and bound are of one run's sizes (not a degenerate zero bound)
    assert 0.01 < s["bound_pos_rmse_m"] < 1.0


def _ukf_with(mean, cov):
    from beacon_sim.filters.base import GaussianBelief
    ukf = build_filter("ukf", _default(), 3)
    ukf.reset(GaussianBelief(np.array(mean, dtype=float), np.array(cov, dtype=float)))
    return ukf


@pytest.mark.parametrize(("cov", "control"), [
    (np.diag([0.04, 0.09, 0.3]), Control(0.8, 0.4)),
    ([[0.5, 0.1, 0.05], [0.1, 0.3, -0.08], [0.05, -0.08, 0.9]], Control(1.5, -0.7)),
    (np.diag([1e-4, 1e-4, 1e-6]), Control(0.3, 0.0)),
])
def test_the_ukf_cross_covariance_is_the_sigma_points_weighted_sum(cov, control):
    """``motion_cross_covariance`` against its definition, written out point by point:
    D = sum_i Wc_i (X_i - m)(f(X_i) - m^-)^T over the filter's own sigma points moved by
    the velocity model, m^- the filter's predicted mean (heading residuals wrapped)."""
    from beacon_sim.core.angles import wrap
    dt = 0.1
    ukf = _ukf_with([1.0, 2.0, 2.9], cov)   # near +-pi: the residuals must wrap
    m = ukf.mean.copy()
    X = ukf._sigma_points()
    Wc = np.array(ukf._weights_now()[1])
    D = ukf.motion_cross_covariance(control, dt)
    np.testing.assert_array_equal(ukf.mean, m)      # it reads the belief, changes nothing
    ukf.predict(control, dt)
    m_pred = ukf.mean
    Y = np.column_stack([X[:, 0] + control.v * dt * np.cos(X[:, 2]),
                         X[:, 1] + control.v * dt * np.sin(X[:, 2]),
                         X[:, 2] + control.omega * dt])
    dY = Y - m_pred
    dY[:, 2] = [wrap(float(a)) for a in dY[:, 2]]
    brute = ((X - m) * Wc[:, None]).T @ dY
    np.testing.assert_allclose(D, brute, rtol=1e-9, atol=1e-12)


def test_the_unscented_gain_is_the_extended_one_for_a_narrow_belief():
    """With a tiny heading spread the velocity model is linear over the sigma points: the
    statistical linearisation D^T P^-1 is the Jacobian at the mean."""
    from beacon_sim.filters.smoothing.rts import statistical_jacobian
    ukf = _ukf_with([0.0, 0.0, 0.7], np.diag([1e-6, 2e-6, 1e-8]))
    u = Control(1.0, 0.3)
    F = statistical_jacobian(ukf.motion_cross_covariance(u, 0.1), ukf.cov)
    np.testing.assert_allclose(F, velocity_jacobian(ukf.mean, 1.0, 0.1), atol=1e-6)


def test_the_unscented_smoother_beats_the_ukf_and_is_consistent_over_seeded_runs():
    """As the EKF's test above, for the UKF with the unscented RTS gain."""
    f = smoothing_monte_carlo(_default(), "ukf", range(500, 508), duration=40.0)
    s, fl = f["smoothed"], f["filtered"]
    assert s["pos_rmse_m"] < 0.85 * fl["pos_rmse_m"]
    assert 2.0 < s["anees"] < 4.5
    assert s["pos_rmse_over_bound"] > 0.8
