"""FastSLAM 2.0's proposal (``slam/fastslam.py``'s docstring has the equations): one reading
folded into K particles' pose proposals with its importance weight, the reading's predictive
distance against them, and the inverse and determinant of the small (1 x 1, 2 x 2) matrices
they need, written out.

Shapes: K particles; a reading z (d,) with noise R (d, d); proposals mu (K, 3) [m, m, rad]
and Sigma (K, 3, 3); the landmark each particle pairs the reading with, means (K, 2) [m] and
covariances (K, 2, 2).
"""

from __future__ import annotations

import math

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.filters.slam.base import innovation, observe


def inv_det(S: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse and determinant of a stack of 1 x 1 or 2 x 2 matrices S (..., d, d), written
    out (numpy's batched solve costs ~1 us per tiny matrix; this, a few numpy calls in all)."""
    if S.shape[-1] == 1:
        det = S[..., 0, 0]
        return 1.0 / S, det
    a, b, c, d = S[..., 0, 0], S[..., 0, 1], S[..., 1, 0], S[..., 1, 1]
    det = a * d - b * c
    inv = np.empty_like(S)
    inv[..., 0, 0] = d / det
    inv[..., 0, 1] = -b / det
    inv[..., 1, 0] = -c / det
    inv[..., 1, 1] = a / det
    return inv, det


def predictive_distance(kind: str, z: np.ndarray, R: np.ndarray, mu: np.ndarray, Sig: np.ndarray,
                        lm: np.ndarray, lc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Squared Mahalanobis distance ``nu^T L^-1 nu`` of one reading for K particles, and
    ``log det(2 pi L)``, with ``L = Hx Sigma Hx^T + Hm C Hm^T + R`` the reading's predictive
    covariance against each particle's proposal (the quantities of :func:`proposal_step`).
    Shapes as there; returns two (K,) arrays."""
    zhat, Hx, Hm = observe(kind, mu, lm)
    nu = innovation(z[None, :], zhat)
    L = Hx @ Sig @ Hx.transpose(0, 2, 1) + Hm @ lc @ Hm.transpose(0, 2, 1) + R
    Linv, det = inv_det(L)
    d = nu.shape[1]
    return np.einsum("ki,kij,kj->k", nu, Linv, nu), np.log(det) + d * math.log(2.0 * math.pi)


def proposal_step(kind: str, z: np.ndarray, R: np.ndarray, mu: np.ndarray, Sig: np.ndarray,
                  lm: np.ndarray, lc: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One reading folded into K particles' pose proposals (the module docstring's equations).

    Parameters
    ----------
    kind, z, R : the reading (d,) and its noise covariance (d, d)
    mu, Sig : ndarray, shapes (K, 3), (K, 3, 3): each particle's proposal so far
    lm, lc : ndarray, shapes (K, 2), (K, 2, 2): the landmark each particle pairs it with

    Returns
    -------
    mu, Sig : the proposals with the reading in
    loglik : ndarray, shape (K,): ``log N(nu; 0, L)``, the factor of the importance weight
    """
    zhat, Hx, Hm = observe(kind, mu, lm)
    nu = innovation(z[None, :], zhat)
    HxT = Hx.transpose(0, 2, 1)
    Z = Hm @ lc @ Hm.transpose(0, 2, 1) + R      # reading noise plus landmark uncertainty
    SHt = Sig @ HxT                               # Sigma Hx^T (K, 3, d)
    L = Hx @ SHt + Z
    Linv, det = inv_det(L)
    K = SHt @ Linv
    mu = mu + np.einsum("kij,kj->ki", K, nu)
    mu[:, 2] = wrap(mu[:, 2])
    Sig = Sig - K @ SHt.transpose(0, 2, 1)
    Sig = 0.5 * (Sig + Sig.transpose(0, 2, 1))
    d = nu.shape[1]
    loglik = -0.5 * (np.einsum("ki,kij,kj->k", nu, Linv, nu) + np.log(det) + d * math.log(2.0 * math.pi))
    return mu, Sig, loglik


__all__ = ["inv_det", "predictive_distance", "proposal_step"]
