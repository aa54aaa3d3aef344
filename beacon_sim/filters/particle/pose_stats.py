"""The summary of a particle set (poses ``[x, y, theta]`` [m, m, rad], world frame): its
weighted mean and covariance (the circular mean heading, heading residuals wrapped, the
covariance clipped to positive definite only when it is not already, a Cholesky test on
floats), and the particles of its dominant mode (``estimate = "cluster"``)."""

from __future__ import annotations

import math

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.filters.particle.fast_calls import eigh3 as _eigh
from beacon_sim.filters.particle.fast_calls import reduce_any as _any
from beacon_sim.filters.particle.fast_calls import reduce_max as _max
from beacon_sim.filters.particle.fast_calls import reduce_min as _min

TWO_PI = 2.0 * math.pi


def weighted_pose_stats(P: np.ndarray, w: np.ndarray, work: np.ndarray | None = None,
                        trig: tuple[np.ndarray, np.ndarray] | None = None
                        ) -> tuple[np.ndarray, np.ndarray]:
    """Mean and covariance of weighted poses.

    Parameters
    ----------
    P : ndarray, shape (3, n) [m, m, rad]
        Rows x, y, theta (float32 or float64; sums are done in that precision).
    w : ndarray, shape (n,)
        Normalised weights.
    work : ndarray, shape (>= 4, >= n), optional
        Scratch space of P's dtype, to avoid allocating.
    trig : (ndarray, ndarray), optional
        ``sin`` and ``cos`` of the headings ``P[2]`` (P's dtype), when already at hand.

    Returns
    -------
    mean : ndarray (3,)
        Weighted mean position and circular mean heading.
    cov : ndarray (3, 3)
        ``sum w e e^T`` with the heading residual wrapped to [-pi, pi).
    """
    n = P.shape[1]
    if work is None:
        work = np.empty((4, n), dtype=P.dtype)
    E = work[:3, :n]
    wt = work[3, :n]
    wt[:] = w
    mx = float(np.dot(wt, P[0]))
    my = float(np.dot(wt, P[1]))
    if trig is None:
        trig = np.sin(P[2], out=E[0]), np.cos(P[2], out=E[1])
    mth = wrap(math.atan2(float(np.dot(wt, trig[0])), float(np.dot(wt, trig[1]))))
    np.subtract(P[0], mx, out=E[0])
    np.subtract(P[1], my, out=E[1])
    e = E[2]
    np.subtract(P[2], mth, out=e)            # in (-2 pi, 2 pi): wrap by at most one turn
    # rarely: test first (the largest and the smallest, one call each; a NaN takes the full
    # test), wrap only then
    if not _max(e) < math.pi and _any(np.greater_equal(e, math.pi)):
        np.subtract(e, TWO_PI, out=e, where=e >= math.pi)
    if not _min(e) >= -math.pi and _any(np.less(e, -math.pi)):
        np.add(e, TWO_PI, out=e, where=e < -math.pi)
    WE = np.multiply(E, wt)
    # 0.5 (C + C^T) in float64 on the entries (exactly numpy's operations: the float32
    # entries are floats exactly, a + b == b + a, and 0.5 (a + a) == a), without three small
    # arrays' calls
    (a00, a01, a02), (a10, a11, a12), (a20, a21, a22) = (WE @ E.T).tolist()
    s01, s02, s12 = 0.5 * (a01 + a10), 0.5 * (a02 + a20), 0.5 * (a12 + a21)
    a00, a11, a22 = 0.5 * (a00 + a00), 0.5 * (a11 + a11), 0.5 * (a22 + a22)
    cov = np.array([[a00, s01, s02], [s01, a11, s12], [s02, s12, a22]])
    if above_entries(a00, s01, s02, a11, s12, a22, 1e-12):  # every eigenvalue above the clip
        return np.array([mx, my, mth]), cov
    # float32 sums can leave a tiny negative eigenvalue when the set has collapsed: clip.
    vals, vecs = _eigh(cov)
    cov = (vecs * np.maximum(vals, 1e-12)) @ vecs.T
    cov = 0.5 * (cov + cov.T)
    return np.array([mx, my, mth]), cov


def above(cov: np.ndarray, floor: float) -> bool:
    """True when the symmetric 3x3 ``cov - floor I`` is positive definite (its Cholesky
    pivots on floats are positive), i.e. every eigenvalue of cov exceeds ``floor``: then the
    eigenvalue clip of :func:`weighted_pose_stats` is the identity, and an eigen-decomposition
    (~50 us) is not needed."""
    (a00, a01, a02), (_, a11, a12), (_, _, a22) = cov.tolist()
    return above_entries(a00, a01, a02, a11, a12, a22, floor)


def above_entries(a00: float, a01: float, a02: float, a11: float, a12: float, a22: float,
                   floor: float) -> bool:
    """:func:`above` of the symmetric 3x3 with these upper-triangle entries."""
    a00 -= floor
    if not a00 > 0.0:
        return False
    l10, l20 = a01 / a00, a02 / a00
    p1 = a11 - floor - l10 * a01
    if not p1 > 0.0:
        return False
    q = a12 - l20 * a01
    return a22 - floor - l20 * a02 - q * q / p1 > 0.0


def dominant_cluster(P: np.ndarray, w: np.ndarray, bounds: tuple[float, float, float, float],
                     cell: float, radius: float) -> np.ndarray:
    """Indices of the particles of the heaviest mode of ``P`` (3, n) with weights ``w`` (n,):
    the coarse x-y ``cell`` [m] of the world's ``bounds`` with the most weight in its 3x3
    neighbourhood, then all particles within ``radius`` [m] of that neighbourhood's
    weighted mean."""
    xmin, ymin, xmax, ymax = bounds
    nx = max(1, math.ceil((xmax - xmin) / cell))
    ny = max(1, math.ceil((ymax - ymin) / cell))
    ix = np.clip(((P[0] - xmin) / cell).astype(np.int64), 0, nx - 1)
    iy = np.clip(((P[1] - ymin) / cell).astype(np.int64), 0, ny - 1)
    H = np.bincount(ix * ny + iy, weights=w, minlength=nx * ny).reshape(nx, ny)
    Hp = np.pad(H, 1)
    S = np.zeros_like(H)
    for a in (-1, 0, 1):
        for b in (-1, 0, 1):
            S += Hp[1 + a: 1 + a + nx, 1 + b: 1 + b + ny]
    cx, cy = np.unravel_index(int(np.argmax(S)), S.shape)
    near = (np.abs(ix - cx) <= 1) & (np.abs(iy - cy) <= 1)
    wn = w[near]
    mx = float(np.dot(wn, P[0][near]) / wn.sum())
    my = float(np.dot(wn, P[1][near]) / wn.sum())
    sel = np.flatnonzero((P[0] - mx) ** 2 + (P[1] - my) ** 2 <= radius * radius)
    return sel if sel.size else np.flatnonzero(near)


__all__ = ["TWO_PI", "above", "above_entries", "dominant_cluster", "weighted_pose_stats"]
