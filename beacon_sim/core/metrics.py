"""Accuracy and consistency measures (design.md section 6).

Errors are estimate minus truth with the heading difference wrapped. NEES is
``e^T P^-1 e`` per step; its average over steps and runs (ANEES) should lie in the
chi-square band when the covariance is honest.
"""

from __future__ import annotations

import math
from statistics import NormalDist

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
    """Normalised estimation error squared per step, shape (T,): ``e^T P^-1 e``."""
    errors = np.asarray(errors, dtype=float)
    covs = np.asarray(covs, dtype=float)
    sol = np.linalg.solve(covs, errors[..., None])[..., 0]
    return np.einsum("ti,ti->t", errors, sol)


def summary(estimates, covs, truths) -> dict[str, float]:
    """Position RMSE [m], heading RMSE [rad], per-axis MSE [m^2, m^2, rad^2] and ANEES."""
    err = pose_errors(estimates, truths)
    mse = np.mean(err**2, axis=0)
    with np.errstate(all="ignore"):
        try:
            anees = float(np.mean(nees(err, covs)))
        except np.linalg.LinAlgError:
            anees = math.inf
    return {
        "pos_rmse_m": float(np.sqrt(mse[0] + mse[1])),
        "heading_rmse_rad": float(np.sqrt(mse[2])),
        "mse_x": float(mse[0]),
        "mse_y": float(mse[1]),
        "mse_theta": float(mse[2]),
        "anees": anees,
    }


def chi2_quantile(p: float, dof: float) -> float:
    """Chi-square quantile by the Wilson-Hilferty cube approximation (exact for dof = 2).

    Accurate to about 1 % at 3 degrees of freedom and better for more, which is all a
    consistency band needs.
    """
    if dof == 2:
        return -2.0 * math.log(1.0 - p)
    z = NormalDist().inv_cdf(p)
    c = 2.0 / (9.0 * dof)
    return dof * (1.0 - c + z * math.sqrt(c)) ** 3


def anees_band(n_samples: int, dof: int = 3, confidence: float = 0.95) -> tuple[float, float]:
    """The two-sided band for the average of ``n_samples`` independent NEES values.

    ``n * ANEES`` is chi-square with ``n * dof`` degrees of freedom for an honest filter.
    """
    a = (1.0 - confidence) / 2.0
    n = max(int(n_samples), 1)
    return chi2_quantile(a, n * dof) / n, chi2_quantile(1.0 - a, n * dof) / n
