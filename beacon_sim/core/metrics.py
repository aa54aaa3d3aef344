"""Accuracy and consistency measures (docs/evaluation.md).

Errors are estimate minus truth with the heading difference wrapped. NEES is
``e^T P^-1 e`` per step; its average over steps and runs (ANEES) should lie in the
chi-square band when the covariance is honest.
"""

from __future__ import annotations

import math

import numpy as np

from beacon_sim.core.angles import diff


def pose_errors(estimates, truths) -> np.ndarray:
    """Errors ``estimate - truth``, shape (T, 3) [m, m, rad], heading wrapped."""
    est = np.asarray(estimates, dtype=float).reshape(-1, 3)
    tru = np.asarray(truths, dtype=float).reshape(-1, 3)
    err = est - tru
    err[:, 2] = diff(est[:, 2], tru[:, 2])
    return err


def nees(errors, covs) -> np.ndarray:
    """Normalised estimation error squared per step, shape (T,): ``e^T P^-1 e``. A step
    whose covariance is singular (no inverse: it rules some error out altogether) has an
    infinite NEES, and only that step: the others keep theirs (one singular covariance
    used to make every step's NEES infinite)."""
    errors = np.asarray(errors, dtype=float)
    covs = np.asarray(covs, dtype=float)
    try:
        sol = np.linalg.solve(covs, errors[..., None])[..., 0]
        return np.einsum("ti,ti->t", errors, sol)
    except np.linalg.LinAlgError:  # one or more singular: each step on its own
        out = np.empty(errors.shape[:-1])
        for t in np.ndindex(out.shape):
            try:
                out[t] = errors[t] @ np.linalg.solve(covs[t], errors[t])
            except np.linalg.LinAlgError:
                out[t] = math.inf
        return out



def summary(estimates, covs, truths) -> dict[str, float]:
    """Position RMSE [m], heading RMSE [rad], per-axis MSE [m^2, m^2, rad^2] and ANEES."""
    err = pose_errors(estimates, truths)
    mse = np.mean(err**2, axis=0)
    with np.errstate(all="ignore"):
        anees = float(np.mean(nees(err, covs)))
    return {
        "pos_rmse_m": float(np.sqrt(mse[0] + mse[1])),
        "heading_rmse_rad": float(np.sqrt(mse[2])),
        "mse_x": float(mse[0]),
        "mse_y": float(mse[1]),
        "mse_theta": float(mse[2]),
        "anees": anees,
    }


def _lower_gamma_regularized(a: float, x: float) -> float:
    """P(a, x), the regularized lower incomplete gamma function: a series below ``a + 1``,
    Lentz's continued fraction for Q = 1 - P above (Numerical Recipes section 6.2)."""
    if x <= 0.0:
        return 0.0
    log_front = a * math.log(x) - x - math.lgamma(a)
    if x < a + 1.0:
        term = total = 1.0 / a
        n = a
        while abs(term) > abs(total) * 1e-16:
            n += 1.0
            term *= x / n
            total += term
        return total * math.exp(log_front)
    tiny = 1e-300
    b = x + 1.0 - a
    c, d = 1.0 / tiny, 1.0 / b
    h = d
    i = 1
    while True:
        an = -i * (i - a)
        b += 2.0
        d = an * d + b
        d = tiny if abs(d) < tiny else d
        c = b + an / c
        c = tiny if abs(c) < tiny else c
        d = 1.0 / d
        delta = d * c
        h *= delta
        i += 1
        if abs(delta - 1.0) < 1e-16 or i > 100_000:
            break
    return 1.0 - math.exp(log_front) * h


def chi2_cdf(x: float, dof: float) -> float:
    """The chi-square distribution function with ``dof`` degrees of freedom."""
    return _lower_gamma_regularized(dof / 2.0, x / 2.0)


def chi2_quantile(p: float, dof: float) -> float:
    """The ``p`` quantile of chi-square with ``dof`` degrees of freedom (exact to about
    1e-10 relative: bisection on :func:`chi2_cdf`). The one source of every consistency
    band and ellipse scale in the program."""
    if not 0.0 < p < 1.0:
        raise ValueError(f"chi2_quantile: p = {p} is not in (0, 1)")
    if dof == 2:
        return -2.0 * math.log1p(-p)
    lo, hi = 0.0, max(dof, 1.0)
    while chi2_cdf(hi, dof) < p:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if chi2_cdf(mid, dof) < p:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-12 * hi:
            break
    return 0.5 * (lo + hi)


def anees_band(n_samples: int, dof: int = 3, confidence: float = 0.95) -> tuple[float, float]:
    """The two-sided band for the average of ``n_samples`` independent NEES values.

    ``n * ANEES`` is chi-square with ``n * dof`` degrees of freedom for an honest filter.
    """
    a = (1.0 - confidence) / 2.0
    n = max(int(n_samples), 1)
    return chi2_quantile(a, n * dof) / n, chi2_quantile(1.0 - a, n * dof) / n
