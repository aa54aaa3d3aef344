"""evaluation.montecarlo.records._check: the eigenvalues are asked only where a 3x3 Cholesky test is
inconclusive, and the verdicts (first unusable estimate and why) are those of eigvalsh on
every matrix, on random and adversarial covariances."""

from __future__ import annotations

import numpy as np

from beacon_sim.evaluation.montecarlo import records as mc
from beacon_sim.hosting.guard import DIVERGED, MAX_COV, MAX_MEAN


def _check_by_eigvalsh(means, covs):
    """_check as it was (eigvalsh of every matrix), with the guard's one divergence rule
    (a mean beyond MAX_MEAN or a covariance entry over MAX_COV, as ``run``)."""
    n = means.shape[0]
    bad = ~(np.all(np.isfinite(means), axis=1) & np.all(np.isfinite(covs), axis=(1, 2)))
    first = int(np.argmax(bad)) if bad.any() else n
    if first < n:
        return first, "estimate() returned NaN or infinity"
    scale = np.maximum(np.max(np.abs(covs), axis=(1, 2)), 1e-12)
    huge = (scale > MAX_COV) | (np.max(np.abs(means), axis=1) > MAX_MEAN)
    asym = np.max(np.abs(covs - np.swapaxes(covs, 1, 2)), axis=(1, 2)) > 1e-6 * scale
    eig = np.linalg.eigvalsh(0.5 * (covs + np.swapaxes(covs, 1, 2)))[:, 0]
    notpsd = eig < -1e-9 * scale
    for mask in (huge, asym, notpsd):
        if mask.any():
            first = min(first, int(np.argmax(mask)))
    if first < n:
        if huge[first]:
            return first, DIVERGED
        return first, ("covariance is not symmetric" if asym[first]
                       else "covariance is not positive semi-definite")
    return n, None


def _covs(rng, n):
    A = rng.normal(size=(n, 3, 3)) * rng.choice([1e-12, 1e-6, 1.0, 1e6], size=(n, 1, 1))
    P = A @ A.swapaxes(1, 2)
    kind = rng.integers(0, 6, n)
    Q, _ = np.linalg.qr(rng.normal(size=(n, 3, 3)))
    lam = rng.uniform(0.1, 10.0, (n, 3))
    lam[:, 0] = rng.choice([0.0, 1e-16, -1e-16, 1e-10, -1e-10, -2e-9, -5e-10, -1e-3], n)
    near = (Q * lam[:, None, :]) @ Q.swapaxes(1, 2)       # an eigenvalue at the threshold's scale
    P = np.where((kind == 1)[:, None, None], near, P)
    P = np.where((kind == 2)[:, None, None], 0.0, P)       # zero covariance (PSD, not PD)
    rank1 = np.einsum("ti,tj->tij", A[:, 0], A[:, 0])
    P = np.where((kind == 3)[:, None, None], rank1, P)
    diag = np.zeros_like(P)
    diag[:, [0, 1, 2], [0, 1, 2]] = rng.choice([-1e-20, 0.0, 1e-30, 1.0], (n, 3))
    return np.where((kind == 4)[:, None, None], diag, P)


def test_check_gives_eigvalsh_verdicts():
    rng = np.random.default_rng(11)
    agree = set()
    for _ in range(400):
        n = int(rng.integers(1, 40))
        covs = _covs(rng, n)
        means = rng.normal(size=(n, 3))
        if rng.random() < 0.1:
            covs[rng.integers(n), 0, 1] += 1e-3 * (1 + abs(covs[0, 0, 0]))   # asymmetric
        if rng.random() < 0.05:
            covs[rng.integers(n), 2, 2] = np.nan
        want = _check_by_eigvalsh(means, covs.copy())
        assert mc._check(means, covs.copy()) == want
        agree.add(want[1])
    assert {None, "covariance is not positive semi-definite"} <= agree
