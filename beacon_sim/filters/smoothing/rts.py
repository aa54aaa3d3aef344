"""The fixed-interval Rauch-Tung-Striebel smoother (Rauch, Tung & Striebel 1965).

A Gaussian filter gives, for every tick k = 1..T, the predicted moments ``(m_k^-, P_k^-)``
(after ``predict``) and the updated ones ``(m_k, P_k)`` (after ``update``), and tick 0's
belief ``(m_0, P_0)``. With ``F_k`` the motion Jacobian of the step k - 1 -> k (at
``m_{k-1}``, the point the filter linearised at), the backward pass is::

    m_T^s = m_T,  P_T^s = P_T
    C_k   = P_k F_{k+1}^T (P_{k+1}^-)^-1                       the smoother gain
    m_k^s = m_k + C_k wrap(m_{k+1}^s - m_{k+1}^-)             heading rows wrapped
    P_k^s = P_k + C_k (P_{k+1}^s - P_{k+1}^-) C_k^T

On a linear-Gaussian model this is exactly the posterior of each state given all the data
(the batch least-squares solution: tests/filters/test_smoothing.py). ``P_k^s <= P_k``: the smoothed
ellipse is never larger than the filtered one.

For the UKF the gain is the unscented RTS smoother's (Sarkka 2008), ``C_k = D_{k+1}
(P_{k+1}^-)^-1`` with ``D_{k+1} = Cov(x_k, x_{k+1}^-)`` from the sigma points the filter
predicted with: the same backward pass with ``F_{k+1}`` replaced by the statistical
linearisation ``D_{k+1}^T P_k^-1`` (:func:`statistical_jacobian`), which gives exactly that gain.

States [x, y, theta] in [m, m, rad], covariances in [m^2, m^2, rad^2].
"""

from __future__ import annotations

import math

import numpy as np

from beacon_sim.core.angles import wrap

#: Index of the heading in the pose state (its differences are wrapped).
HEADING = 2


def velocity_jacobian(mean: np.ndarray, v: float, dt: float) -> np.ndarray:
    """F = d f / d x (3, 3) of the velocity model ``x += v dt cos th, y += v dt sin th,
    th += w dt`` at ``mean`` [m, m, rad] for the command speed ``v`` [m/s] over ``dt`` [s]."""
    th = float(mean[HEADING])
    return np.array([[1.0, 0.0, -v * dt * math.sin(th)],
                     [0.0, 1.0, v * dt * math.cos(th)],
                     [0.0, 0.0, 1.0]])


def statistical_jacobian(D: np.ndarray, P: np.ndarray) -> np.ndarray:
    """``F = D^T P^-1`` (n, n): the linear map that a prediction with cross-covariance ``D =
    Cov(x_k, x_{k+1}^-)`` from the belief covariance ``P`` amounts to, so that the RTS gain
    ``P F^T (P^-)^-1`` is ``D (P^-)^-1``. A singular ``P`` (no spread on some axis, so no
    cross-covariance there either) by the pseudo-inverse."""
    try:
        return np.linalg.solve(P, D).T
    except np.linalg.LinAlgError:
        return (np.linalg.pinv(P, hermitian=True) @ D).T


def smoother_gain(P: np.ndarray, F: np.ndarray, P_pred: np.ndarray) -> np.ndarray:
    """``C = P F^T (P_pred)^-1`` (n, n), by a solve; a singular ``P_pred`` (a known start
    with no process noise on some axis) by the pseudo-inverse, which gives C = 0 there."""
    PFt = P @ F.T
    try:
        return np.linalg.solve(P_pred.T, PFt.T).T
    except np.linalg.LinAlgError:
        return PFt @ np.linalg.pinv(P_pred, hermitian=True)


def rts_step(m: np.ndarray, P: np.ndarray, F: np.ndarray, m_pred: np.ndarray, P_pred: np.ndarray,
             m_next_s: np.ndarray, P_next_s: np.ndarray, angles: tuple[int, ...] = (HEADING,)
             ) -> tuple[np.ndarray, np.ndarray]:
    """One backward step: tick k's smoothed ``(m_k^s, P_k^s)`` from its filtered moments
    ``(m, P)``, the next tick's Jacobian ``F``, predicted moments and smoothed moments.
    ``angles``: the state rows that are angles (their differences and results wrapped)."""
    C = smoother_gain(P, F, P_pred)
    d = m_next_s - m_pred
    for i in angles:
        d[i] = wrap(float(d[i]))
    ms = m + C @ d
    for i in angles:
        ms[i] = wrap(float(ms[i]))
    Ps = P + C @ (P_next_s - P_pred) @ C.T
    return ms, 0.5 * (Ps + Ps.T)


def rts_smooth(means: np.ndarray, covs: np.ndarray, pred_means: np.ndarray, pred_covs: np.ndarray,
               jacobians: np.ndarray, angles: tuple[int, ...] = (HEADING,)
               ) -> tuple[np.ndarray, np.ndarray]:
    """The smoothed moments of ticks 0..T.

    Parameters
    ----------
    means, covs : arrays (T + 1, n), (T + 1, n, n)
        Filtered moments: row 0 the initial belief, row k after tick k's update.
    pred_means, pred_covs : arrays (T, n), (T, n, n)
        Row k - 1: the moments after tick k's prediction.
    jacobians : array (T, n, n)
        Row k - 1: ``F_k``, the motion Jacobian of tick k's prediction.
    angles : the state rows that are angles.

    Returns
    -------
    (means (T + 1, n), covs (T + 1, n, n)): the smoothed moments.
    """
    means = np.asarray(means, dtype=float)
    covs = np.asarray(covs, dtype=float)
    T = means.shape[0] - 1
    if pred_means.shape[0] != T or pred_covs.shape[0] != T or jacobians.shape[0] != T:
        raise ValueError(f"rts_smooth: {T + 1} filtered moments need {T} predicted moments and "
                         f"Jacobians, got {pred_means.shape[0]}, {pred_covs.shape[0]}, {jacobians.shape[0]}")
    ms = means.copy()
    Ps = covs.copy()
    for k in range(T - 1, -1, -1):
        ms[k], Ps[k] = rts_step(means[k], covs[k], jacobians[k], pred_means[k], pred_covs[k],
                                ms[k + 1], Ps[k + 1], angles)
    return ms, Ps


__all__ = ["HEADING", "rts_smooth", "rts_step", "smoother_gain", "statistical_jacobian", "velocity_jacobian"]
