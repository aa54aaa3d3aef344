"""Per-particle maximum-likelihood association (:func:`particle_ml_association`): for every
particle (poses (N, 3) [m, m, rad]) and reading, the most likely beacon and its
log-likelihood, vectorised over particles; :func:`particle_d2` the squared Mahalanobis
distances it (and the grid filter's hook) uses."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from beacon_sim.core import measurement_models as mm
from beacon_sim.core.angles import wrap_into
from beacon_sim.filters.association.linearised import check_readings, gate


def particle_ml_association(kind: str, z: np.ndarray, poses: np.ndarray, beacon_xy: np.ndarray,
                            reading_std: Sequence[float], prob: float | None = None
                            ) -> tuple[np.ndarray, np.ndarray]:
    """Per particle and reading, the maximum-likelihood beacon and its log-likelihood.

    Each particle is a pose with no uncertainty of its own, so the likelihood of reading i
    from beacon j is the Gaussian ``N(nu_ij; 0, R)`` (diagonal R, bearing residual wrapped).
    Readings are associated independently (two readings may pick the same beacon), as in
    FastSLAM's per-particle maximum likelihood.

    Parameters
    ----------
    kind, z, beacon_xy, reading_std : as in :func:`linearise`
    poses : ndarray, shape (N, 3) [m, m, rad]
    prob : float, optional
        When given, a best beacon whose squared distance ``nu^T R^-1 nu`` exceeds
        ``gate(prob, d)`` is rejected: its index becomes -1 (the log-likelihood stays the
        best beacon's, for the caller to replace by a clutter density if it wants).

    Returns
    -------
    best : ndarray of int, shape (N, m)
        Row index into ``beacon_xy`` of each particle's choice for each reading (-1: gated out).
    loglik : ndarray, shape (N, m)
        ``log N(nu; 0, R)`` of that choice (includes the Gaussian's normalising constant).
    """
    best, d2_best = particle_d2(kind, z, poses, beacon_xy, reading_std)
    r = check_readings(kind, z, beacon_xy, reading_std)[2]
    log_norm = -0.5 * (r.size * math.log(2.0 * math.pi) + float(np.sum(np.log(r))))
    loglik = log_norm - 0.5 * d2_best
    if prob is not None:
        best = np.where(d2_best <= gate(prob, r.size), best, -1)
    return best, loglik


def particle_d2(kind: str, z: np.ndarray, poses: np.ndarray, beacon_xy: np.ndarray,
                 reading_std: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """Per particle and reading, the nearest beacon row (N, m) and its squared distance
    ``nu^T R^-1 nu`` (N, m) (``inf`` when there is no beacon)."""
    z, xy, r = check_readings(kind, z, beacon_xy, reading_std)
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    n_part, m, n = poses.shape[0], z.shape[0], xy.shape[0]
    if n == 0 or m == 0:
        return np.full((n_part, m), -1, dtype=int), np.full((n_part, m), np.inf)
    # Reading by reading on (N, n) arrays kept for the whole call: a working set that stays in
    # cache and no fresh (N, m, n) arrays (each one a page fault per 4 KB); the arithmetic is
    # the one it replaced, element by element, so the bits are the same.
    bear = mm.bearing_many(poses, xy)
    rng = mm.range_many(poses, xy) if kind == "range_bearing" else None
    d2 = np.empty((n_part, n))
    tmp = np.empty((n_part, n))
    inv_b, inv_r = 1.0 / r[-1], 1.0 / r[0]
    best = np.empty((n_part, m), dtype=np.intp)
    d2_best = np.empty((n_part, m))
    rows = np.arange(n_part)
    for i in range(m):
        np.subtract(z[i, -1], bear, out=d2)
        wrap_into(d2, tmp)
        np.multiply(d2, d2, out=d2)
        d2 *= inv_b
        if rng is not None:
            np.subtract(z[i, 0], rng, out=tmp)
            tmp *= tmp
            tmp *= inv_r
            d2 += tmp
        d2[np.isnan(d2)] = np.inf  # a reading or pose that is not a number fits no beacon
        b = np.argmin(d2, axis=1)  # first minimum: ties go to the lower beacon row
        best[:, i] = b
        d2_best[:, i] = d2[rows, b]
    return best, d2_best
