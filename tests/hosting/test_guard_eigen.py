"""The covariance guard agrees with an eigenvalue test: a covariance is refused as "not
positive semi-definite" exactly when ``eigvalsh`` finds an eigenvalue below
``-PSD_TOLERANCE * max|entry|``, except within ``PSD_AGREEMENT * max|entry|`` of that
threshold. The case that cried wolf: MCL's collapsed cloud, eigenvalues 1.0e-12, 1.3e-12 and
0.027, was refused by a determinant test that lost to rounding."""

from __future__ import annotations

import numpy as np
import pytest

from beacon_sim.hosting.guard import PSD_AGREEMENT, PSD_TOLERANCE, _not_psd, validate_estimate


def _rotation(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.diag(r))


def _with_eigenvalues(rng: np.random.Generator, values) -> np.ndarray:
    q = _rotation(rng)
    c = q @ np.diag(values) @ q.T
    return 0.5 * (c + c.T)


def _verdicts(c: np.ndarray) -> tuple[bool, bool]:
    """(the fast path's refusal, the general path's refusal) of covariance ``c``."""
    fast = validate_estimate((np.zeros(3), c.copy())) == "covariance is not positive semi-definite"
    (a, b, d), (_, e, f), (_, _, g) = c.tolist()
    return fast, _not_psd(a, b, d, e, f, g)


def test_the_collapsed_cloud_of_the_office_soak_is_accepted():
    rng = np.random.default_rng(5080)
    for _ in range(2000):
        c = _with_eigenvalues(rng, [1.0e-12, 1.3e-12, 0.027])
        assert _verdicts(c) == (False, False)


@pytest.mark.parametrize("seed", range(4))
def test_the_guard_agrees_with_eigvalsh_within_the_stated_tolerance(seed):
    rng = np.random.default_rng(seed)
    checked = disagreements = refused = 0
    for _ in range(20000):
        big = 10.0 ** rng.uniform(-6, 4)
        # the smallest eigenvalues around the threshold and around zero, on either side
        small = big * rng.choice([1, -1]) * 10.0 ** rng.uniform(-16, -6, size=2)
        c = _with_eigenvalues(rng, [big, *small])
        scale = np.abs(c).max()
        lam = np.linalg.eigvalsh(c).min()
        truth = lam < -PSD_TOLERANCE * scale
        near = abs(lam + PSD_TOLERANCE * scale) <= PSD_AGREEMENT * scale
        fast, general = _verdicts(c)
        assert fast == general
        checked += 1
        refused += truth
        if not near and fast != truth:
            disagreements += 1
    assert disagreements == 0
    assert 0.2 * checked < refused < 0.8 * checked  # both verdicts were exercised


def test_a_clearly_negative_eigenvalue_is_still_refused():
    rng = np.random.default_rng(1)
    for _ in range(500):
        c = _with_eigenvalues(rng, [1.0, 0.5, -1e-8])
        assert _verdicts(c) == (True, True)
