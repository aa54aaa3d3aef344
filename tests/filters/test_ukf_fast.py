"""The UKF's hot paths on Python floats against the straightforward numpy
formulation of the same equations, on random cases: the closed-form prediction, the update
for a few readings (floats, and S solved on arrays), gating, wide headings (the limited
spread), and angles near +-pi. Agreement to 1e-9."""

from __future__ import annotations

import math

import numpy as np
import pytest
from gaussian_helpers import bearing, context, pose_fix, position_fix, range_bearing

from beacon_sim.core.angles import wrap
from beacon_sim.core.types import Control
from beacon_sim.filters.base import GaussianBelief
from beacon_sim.filters.gaussian import ukf as ukf_mod
from beacon_sim.filters.gaussian.ukf import UnscentedKalmanFilter, heading_limited_weights, robust_sqrt

BEACONS = ((1, 2.0, 2.0), (2, 8.0, 2.0), (3, 8.0, 8.0), (4, 2.0, 8.0), (5, -5.0, 0.001), (6, 0.5, 9.0))
PARAMS = [{}, {"scaled": False, "kappa": 1.0}, {"alpha": 0.5, "beta": 2.0}, {"gate_chi2": 6.0},
          {"gate_chi2": 2.0, "alpha": 0.8}]


def sigma(f: UnscentedKalmanFilter, mean: np.ndarray, P: np.ndarray):
    """Sigma points (7, 3) and weights, written from the equations."""
    c = f.c
    sc, Wm, Wc = heading_limited_weights(c, f.Wm, f.Wc, float(P[2, 2]))
    try:
        L = np.linalg.cholesky(P)
    except np.linalg.LinAlgError:
        L = robust_sqrt(P)
    A = (sc * L).T                                   # rows: the columns of sqrt(c P)
    D = np.vstack([np.zeros(3), A, -A])
    return mean + D, D, np.asarray(Wm, float), np.asarray(Wc, float)


def angle_mean(Z: np.ndarray, Wm: np.ndarray) -> np.ndarray:
    if Wm[0] < 0.0:
        return Z[0] + Wm @ wrap(Z - Z[0])
    return np.arctan2(Wm @ np.sin(Z), Wm @ np.cos(Z))


def reference_predict(f, mean, P, v, w, dt):
    X, _, Wm, Wc = sigma(f, mean, P)
    th = X[:, 2]
    Y = np.column_stack([X[:, 0] + v * dt * np.cos(th), X[:, 1] + v * dt * np.sin(th), th + w * dt])
    m = np.array([Wm @ Y[:, 0], Wm @ Y[:, 1], angle_mean(Y[:, 2], Wm)])
    if Wm[0] < 0.0:
        m[2] = mean[2] + w * dt
    d = Y - m
    d[:, 2] = wrap(d[:, 2])
    Q = f.ctx.motion_noise.process_cov(mean, v, w, dt)
    m[2] = wrap(m[2])
    return m, (d.T * Wc) @ d + Q


def reference_update(f, mean, P, measurements, gate):
    """The stacked UKF update with matrix inverses; returns (mean, P, rejected)."""
    X, D, Wm, Wc = sigma(f, mean, P)
    xy = {b.id: (b.x, b.y) for b in f.ctx.world.beacons}
    Zs, zs, rs, angle, blocks = [], [], [], [], []
    for m in measurements:
        spec = f.ctx.sensor(m.sensor)
        if m.kind in ("bearing", "range_bearing"):
            var = [s * s for s in spec.reading_std()]
            for zrow, bid in zip(m.z, m.beacon_ids, strict=True):
                bx, by = xy[int(bid)]
                start = len(zs)
                if m.kind == "range_bearing":
                    Zs.append(np.hypot(bx - X[:, 0], by - X[:, 1]))
                    zs.append(zrow[0])
                    rs.append(var[0])
                    angle.append(False)
                Zs.append(np.arctan2(by - X[:, 1], bx - X[:, 0]) - X[:, 2])
                zs.append(zrow[-1])
                rs.append(var[-1])
                angle.append(True)
                blocks.append((start, len(zs)))
        else:
            var = [s * s for s in spec.fix_std(len(m.beacon_ids), m.hdop)]
            n = 3 if m.kind == "pose" else 2
            start = len(zs)
            for i in range(n):
                Zs.append(X[:, i].copy())
                zs.append(m.z.reshape(-1)[i])
                rs.append(var[i])
                angle.append(i == 2)
            blocks.append((start, len(zs)))
    Z = np.array(Zs).T                              # (7, m)
    zhat = np.array([angle_mean(Z[:, j], Wm) if a else Wm @ Z[:, j] for j, a in enumerate(angle)])
    dZ = Z - zhat
    nu = np.array(zs) - zhat
    for j, a in enumerate(angle):
        if a:
            dZ[:, j] = wrap(dZ[:, j])
            nu[j] = wrap(nu[j])
    S = dZ.T @ np.diag(Wc) @ dZ + np.diag(rs)
    Pxz = D.T @ np.diag(Wc) @ dZ
    keep = np.ones(len(zs), bool)
    rejected = 0
    if gate > 0.0:
        for i, j in blocks:
            if nu[i:j] @ np.linalg.inv(S[i:j, i:j]) @ nu[i:j] > gate:
                keep[i:j] = False
                rejected += 1
        if not keep.any():
            return mean, P, rejected
    S, Pxz, nu = S[np.ix_(keep, keep)], Pxz[:, keep], nu[keep]
    K = Pxz @ np.linalg.inv(S)
    m = mean + K @ nu
    m[2] = wrap(m[2])
    return m, P - K @ S @ K.T, rejected


def random_cov(rng, wide=False):
    A = rng.normal(size=(3, 3)) * rng.uniform(0.02, 0.4, 3)
    P = A @ A.T + np.diag([1e-4, 1e-4, 1e-5])
    if wide:
        P[2, 2] += rng.uniform(0.5, 4.0)              # heading std up to 2 rad: the limited spread
    return P


def random_measurements(rng, f, mean):
    """One to three sensors' readings near the truth, some bearings near +-pi."""
    out = []
    truth = mean + rng.normal(0, 0.05, 3)
    kinds = rng.choice(["bearing", "range_bearing", "pose", "position"], size=rng.integers(1, 3),
                       replace=False)
    for kind in kinds:
        if kind in ("bearing", "range_bearing"):
            ids = rng.choice([b.id for b in f.ctx.world.beacons], size=rng.integers(1, 5), replace=False)
            xy = np.array([[b.x, b.y] for b in f.ctx.world.beacons if b.id in set(ids.tolist())])
            ids = np.array([b.id for b in f.ctx.world.beacons if b.id in set(ids.tolist())])
            d = xy - truth[:2]
            brg = wrap(np.arctan2(d[:, 1], d[:, 0]) - truth[2] + rng.normal(0, 0.05, len(ids)))
            if rng.random() < 0.2:
                brg[0] = wrap(brg[0] + math.pi)       # an outlier (the gate's)
            if kind == "bearing":
                out.append(bearing(brg, ids))
            else:
                rng_ = np.hypot(d[:, 0], d[:, 1]) + rng.normal(0, 0.1, len(ids))
                out.append(range_bearing(np.column_stack([rng_, brg]), ids))
        elif kind == "pose":
            out.append(pose_fix([truth[0], truth[1], wrap(truth[2] + 0.05)], n_beacons=2))
        else:
            out.append(position_fix(truth[:2] + rng.normal(0, 0.02, 2)))
    return out


def close(m1, P1, m2, P2, tol=1e-9):
    d = np.abs(np.asarray(m1) - m2)
    d[2] = min(d[2], 2 * math.pi - d[2])
    scale = max(1.0, float(np.abs(P2).max()))
    return d.max() < tol and np.abs(np.asarray(P1) - P2).max() < tol * scale


def headings(rng):
    return [rng.uniform(-math.pi, math.pi), math.pi - 1e-3, -math.pi + 1e-4, math.pi - 1e-12]


@pytest.mark.parametrize("params", PARAMS)
def test_closed_form_prediction_equals_the_sigma_point_loop(params):
    rng = np.random.default_rng(1)
    f = UnscentedKalmanFilter(context(params, beacons=BEACONS))
    for trial in range(60):
        th = headings(rng)[trial % 4]
        mean = np.array([rng.uniform(-5, 5), rng.uniform(-5, 5), th])
        P = random_cov(rng, wide=trial % 3 == 0)
        v, w = rng.uniform(-1.5, 1.5), rng.uniform(-2, 2)
        f.reset(GaussianBelief(mean, P))
        f.predict(Control(v, w), 0.1)
        got = f.estimate()
        want = reference_predict(f, mean, P, v, w, 0.1)
        assert close(*got, *want), (trial, got, want)
        f.reset(GaussianBelief(mean, P))               # and the loop it replaces
        f._predict_points(v, w, 0.1, f._columns(), *f._weights_now())
        assert close(*f.estimate(), *want)


@pytest.mark.parametrize("params", PARAMS)
@pytest.mark.parametrize("solve_rows", [0, 100])     # S solved on arrays / on floats
def test_update_on_floats_equals_the_numpy_formulation(monkeypatch, params, solve_rows):
    monkeypatch.setattr(ukf_mod, "FLOAT_SOLVE_ROWS", solve_rows)
    monkeypatch.setattr(ukf_mod, "FLOAT_ROWS", 100)
    rng = np.random.default_rng(2)
    f = UnscentedKalmanFilter(context(params, beacons=BEACONS))
    gate = float(params.get("gate_chi2", 0.0))
    used = rejected = 0
    for trial in range(80):
        th = headings(rng)[trial % 4]
        mean = np.array([rng.uniform(-3, 9), rng.uniform(-3, 9), th])
        P = random_cov(rng, wide=trial % 5 == 0)
        ms = random_measurements(rng, f, mean)
        f.reset(GaussianBelief(mean, P))
        before = f.rejected
        assert f._update_floats(ms)
        used += 1
        m, Pn, rej = reference_update(f, mean, P, ms, gate)
        assert f.rejected - before == rej
        rejected += rej
        assert close(*f.estimate(), m, Pn), (trial, ms)
        f.reset(GaussianBelief(mean, P))               # and the array form, as before
        f.rejected = before
        f._update_arrays(ms)
        assert close(*f.estimate(), m, Pn)
        assert f.rejected - before == rej
    assert used == 80
    if gate:
        assert rejected > 0


def test_bearings_straddling_pi_on_floats():
    """Beacon 5 straight behind the robot: the sigma points' bearings lie on both sides of
    +-pi, the reading at -pi + 0.01; floats and numpy agree."""
    f = UnscentedKalmanFilter(context(beacons=BEACONS))
    for th in (0.0, 1e-9, -1e-9, 0.02):
        mean, P = np.array([0.0, 0.0, th]), np.diag([0.01, 0.01, 0.1])
        ms = [bearing([-math.pi + 0.01], [5]), range_bearing([[5.0, math.pi - 0.002]], [5])]
        f.reset(GaussianBelief(mean, P))
        f.update(ms)
        m, Pn, _ = reference_update(f, mean, P, ms, 0.0)
        assert close(*f.estimate(), m, Pn)


def test_a_non_positive_pivot_hands_over_to_the_arrays(monkeypatch):
    """A negative centre weight can make S indefinite: the float path declines (nothing
    changed) and the LU solve of the array form decides."""
    f = UnscentedKalmanFilter(context(beacons=BEACONS))
    f.reset(GaussianBelief(np.array([1.0, 1.0, 0.2]), np.diag([0.04, 0.04, 0.01])))
    monkeypatch.setattr(ukf_mod, "_conditioned_floats", lambda *a: None)
    calls = []
    real = f._update_arrays
    monkeypatch.setattr(f, "_update_arrays", lambda ms: calls.append(1) or real(ms))
    m0 = f.estimate()
    ms = [bearing([0.5], [1])]
    f.update(ms)
    assert calls == [1]
    want = reference_update(f, m0[0], m0[1], ms, 0.0)
    assert close(*f.estimate(), want[0], want[1])
