"""hosting/runner.validate_estimate: the fast path for plain float64 arrays gives the
verdicts of the full check on random and adversarial estimates (NaN, infinity, sums that
overflow, asymmetric, not PSD, huge), and anything unusual takes the full check."""

from __future__ import annotations

import math

import numpy as np

from beacon_sim.hosting.guard import _validate_any, validate_estimate


def _same(a, b) -> bool:
    if isinstance(a, str) or isinstance(b, str):
        return a == b
    return all(np.array_equal(x, y) and x.dtype == y.dtype for x, y in zip(a, b, strict=True))


def _cases(rng: np.random.Generator, n: int):
    for _ in range(n):
        A = rng.normal(size=(3, 3)) * rng.choice([1e-12, 1e-6, 1.0, 1e6, 1e7])
        P = A @ A.T
        m = rng.normal(size=3) * rng.choice([1.0, 1e8, 2e9])
        k = rng.integers(0, 11)
        if k == 1:
            P[rng.integers(3), rng.integers(3)] = rng.choice([np.nan, np.inf, -np.inf])
        elif k == 2:
            m[rng.integers(3)] = rng.choice([np.nan, np.inf])
        elif k == 3:
            P = np.full((3, 3), 1e308)  # finite entries whose sum overflows
        elif k == 4:
            P[0, 1] += 1e-3 * (1.0 + abs(P[0, 0]))  # asymmetric
        elif k == 5:
            Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
            lam = np.array([rng.choice([0.0, -1e-16, -2e-9, -1e-3, 1e-10]), 1.0, 2.0])
            P = (Q * lam) @ Q.T  # an eigenvalue at the threshold's scale
        elif k == 6:
            P = np.zeros((3, 3))
        elif k == 7:
            m = np.array([1e308, 1e308, 1e308])  # finite, sum overflows
        elif k in (8, 9):  # off by one ulp from symmetric (the general branch), PSD at the threshold
            Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
            lam = np.array([rng.choice([0.0, -1e-16, -2e-9, -1e-3, 1e-10]), 1.0, 2.0])
            P = (Q * lam) @ Q.T
            P = 0.5 * (P + P.T)
            if k == 9:
                i, j = rng.choice(3, size=2, replace=False)
                P[i, j] = np.nextafter(P[i, j], np.inf)
        yield m, P


def test_fast_path_verdicts_equal_the_full_check():
    rng = np.random.default_rng(16)
    kinds = set()
    for m, P in _cases(rng, 5000):
        fast = validate_estimate((m, P))
        full = _validate_any((m, P))
        assert _same(fast, full), (m, P, fast, full)
        kinds.add(fast if isinstance(fast, str) else "ok")
    assert {"ok", "estimate() returned NaN or infinity", "covariance is not symmetric",
            "covariance is not positive semi-definite"} <= kinds
    assert any("diverged" in k for k in kinds)


def test_both_branches_are_exercised():
    """The exactly symmetric branch and the general one both give verdicts of each kind."""
    sym = np.diag([1.0, 2.0, 3.0])
    sym[0, 1] = sym[1, 0] = 0.5
    off = sym.copy()
    off[0, 1] = np.nextafter(0.5, 1.0)
    for P in (sym, off):
        assert isinstance(validate_estimate((np.zeros(3), P)), tuple)
        neg = P.copy()
        neg[2, 2] = -1.0
        assert validate_estimate((np.zeros(3), neg)) == _validate_any((np.zeros(3), neg)) \
            == "covariance is not positive semi-definite"
        assert "diverged" in validate_estimate((np.zeros(3), P * 1e13))


def test_unusual_inputs_take_the_full_check():
    good = np.zeros(3), np.eye(3)
    assert isinstance(validate_estimate(good), tuple)
    r = validate_estimate((np.zeros(3, dtype=np.float32), np.eye(3, dtype=np.float32)))
    assert isinstance(r, tuple) and r[0].dtype == np.float64  # converted, as before
    assert validate_estimate(([0, 0, 0], np.eye(3).tolist()))[1].shape == (3, 3)
    assert "shapes" in validate_estimate((np.zeros(2), np.eye(3)))
    assert "expected a (mean, cov) pair" in validate_estimate(np.zeros(3))
    out = validate_estimate(good)
    assert out[0] is not good[0] and out[1] is not good[1]  # fresh copies
    assert math.isfinite(float(out[1][0, 0]))


def test_other_shapes_of_three_and_nine_entries_get_the_full_checks_message():
    # the fast path checks sizes and lets the unpacking settle the shape
    means = [np.zeros(3), np.zeros((3, 1)), np.zeros((1, 3)), np.zeros((1, 1, 3))]
    covs = [np.eye(3), np.eye(3).reshape(9), np.eye(3).reshape(1, 9), np.eye(3).reshape(3, 3, 1),
            np.eye(3).reshape(1, 3, 3), np.eye(3).reshape(9, 1)]
    for m in means:
        for c in covs:
            got, full = validate_estimate((m, c)), _validate_any((m, c))
            assert _same(got, full), (m.shape, c.shape, got, full)
            assert isinstance(got, tuple) == (m.shape == (3,) and c.shape == (3, 3))
