"""Geometry in metres that the sensors and the drawing share.

Ellipse outlines, the sensor disc and HDOP are computed here so that ``render`` only
converts metres to pixels.
"""

from __future__ import annotations

import numpy as np

from beacon_sim.core.metrics import chi2_quantile

#: Chi-square quantiles for 2 degrees of freedom: the ellipse that holds this share of mass.
CHI2_2DOF = {p: chi2_quantile(p, 2) for p in (0.95, 0.99, 0.6827)}


def covariance_ellipse(mean_xy, cov_xy, scale2: float = CHI2_2DOF[0.95], n: int = 48):
    """Outline of ``{p : (p - mean)^T cov^-1 (p - mean) = scale2}``, shape (n, 2) [m].

    ``scale2`` is the squared Mahalanobis radius: 5.991 gives the 95 % ellipse of a 2-D
    Gaussian. A singular or slightly indefinite covariance is handled (clamped to >= 0).
    """
    cov_xy = 0.5 * (np.asarray(cov_xy, dtype=float) + np.asarray(cov_xy, dtype=float).T)
    vals, vecs = np.linalg.eigh(cov_xy)
    radii = np.sqrt(np.clip(vals, 0.0, None) * scale2)
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    unit = np.stack([np.cos(t), np.sin(t)], axis=1)
    return np.asarray(mean_xy, dtype=float) + (unit * radii) @ vecs.T


def circle(center_xy, radius: float, n: int = 64):
    """Outline of a circle (e.g. the sensor range disc), shape (n, 2) [m]."""
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    return np.asarray(center_xy, dtype=float) + radius * np.stack([np.cos(t), np.sin(t)], 1)


def hdop(xy, beacon_xy, height: float = 0.0):
    """Horizontal dilution of precision of a range-based position fix.

    Each beacon contributes the row ``[dx, dy] / r`` of the geometry matrix G, where
    ``(dx, dy)`` is the horizontal offset from the beacon to the receiver and
    ``r = sqrt(dx^2 + dy^2 + height^2)`` the slant range (beacons ``height`` metres above
    the receiver, as seed 002's ceiling beacons). ``HDOP = sqrt(trace((G^T G)^-1))``.

    Parameters
    ----------
    xy : array_like, shape (2,) or (N, 2) [m]
        Receiver position(s).
    beacon_xy : array_like, shape (m, 2) [m]
        The beacons used for the fix.

    Returns
    -------
    float or ndarray (N,)
        HDOP (dimensionless); ``inf`` when the geometry does not fix the position
        (fewer than two beacons, or all on one line through the receiver).
    """
    xy = np.asarray(xy, dtype=float)
    single = xy.ndim == 1
    p = xy.reshape(-1, 2)
    b = np.asarray(beacon_xy, dtype=float).reshape(-1, 2)
    d = p[:, None, :] - b[None, :, :]  # (N, m, 2)
    r = np.sqrt(np.sum(d * d, axis=2) + height * height)
    g = d / np.maximum(r, 1e-12)[..., None]
    # G^T G for each receiver position: [[a, c], [c, e]]
    a = np.sum(g[..., 0] ** 2, axis=1)
    e = np.sum(g[..., 1] ** 2, axis=1)
    c = np.sum(g[..., 0] * g[..., 1], axis=1)
    det = a * e - c * c
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.where(det > 1e-12 * np.maximum(a + e, 1e-300) ** 2,
                       np.sqrt((a + e) / det), np.inf)
    return float(out[0]) if single else out
