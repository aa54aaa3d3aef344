"""Hyperbolic trilateration: a position fix from range differences (TDOA) against a
reference beacon, with its covariance from the geometry (the loose coupling of seed 002).

Method: Gauss-Newton on the weighted least-squares cost ``nu^T C^-1 nu`` (nu = measured minus
expected differences, C = I + 1 1^T, the differences' true correlation), started from the
beacons' centroid and from eight points around it (a hyperbola pair can meet twice); the
lowest cost wins. Not the seed's Cayley-Menger bideterminant closed form: Gauss-Newton is
the maximum-likelihood fix for Gaussian arrivals and gives the covariance on the way.

The fix's covariance is ``s^2 (D^T C^-1 D)^-1`` at the fix (D the differences' x-y Jacobian,
s the noise of one arrival): its ellipse is the geometry's; ``HDOP = sqrt(trace) / s``.
The receiver's height is known: beacons are ``height`` metres above it. Units: metres,
world frame.

Errors (:class:`TrilaterationError`, one line): fewer than two differences, beacons at one
point, a geometry that does not fix the position (collinear beacons seen from their line),
two fixes that explain the differences equally well (ambiguous), no convergence.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Gauss-Newton steps at most, and the step [m] below which it has converged.
MAX_STEPS = 30
TOL_M = 1e-9

#: Two minima whose costs differ by less than this (in chi-square units of one fix) and
#: whose positions differ by more than :data:`AMBIGUOUS_M` make the fix ambiguous.
AMBIGUOUS_COST = 1.0
AMBIGUOUS_M = 0.05

#: Condition number of D^T C^-1 D above which the geometry is taken as degenerate.
MAX_CONDITION = 1e10


class TrilaterationError(ValueError):
    """The differences do not give one position (the message says why, on one line)."""


@dataclass(frozen=True)
class Fix:
    """A trilaterated position ``xy`` (2,) [m], its covariance ``cov`` (2, 2) [m^2],
    ``hdop`` (sqrt(trace(cov)) / s) and the weighted cost at the fix (chi-square, k - 2
    degrees of freedom)."""

    xy: np.ndarray
    cov: np.ndarray
    hdop: float
    cost: float


def _normal(x: float, y: float, z: list[float], bxy: list[tuple[float, float]], height: float
            ) -> tuple[float, float, float, float, float, float]:
    """At (x, y): the normal matrix ``A = D^T C^-1 D`` as (a, c, e), ``b = D^T C^-1 nu`` and
    the cost ``nu^T C^-1 nu`` [m^2], on Python floats (+, *, /, sqrt: the same bits on every
    machine). ``C^-1 = I - 1 1^T / (k + 1)`` (Sherman-Morrison)."""
    h2 = height * height
    rx, ry = x - bxy[0][0], y - bxy[0][1]
    r0 = math.sqrt(rx * rx + ry * ry + h2)
    g0x, g0y = rx / r0, ry / r0
    k = len(z)
    nus, dxs, dys = [], [], []
    for i in range(k):
        dx, dy = x - bxy[i + 1][0], y - bxy[i + 1][1]
        r = math.sqrt(dx * dx + dy * dy + h2)
        nus.append(z[i] - (r - r0))
        dxs.append(dx / r - g0x)
        dys.append(dy / r - g0y)
    w = 1.0 / (k + 1)
    sn, sx, sy = sum(nus), sum(dxs), sum(dys)
    a = sum(u * u for u in dxs) - w * sx * sx
    e = sum(v * v for v in dys) - w * sy * sy
    c = sum(u * v for u, v in zip(dxs, dys, strict=True)) - w * sx * sy
    bx = sum(u * n for u, n in zip(dxs, nus, strict=True)) - w * sx * sn
    by = sum(v * n for v, n in zip(dys, nus, strict=True)) - w * sy * sn
    cost = sum(n * n for n in nus) - w * sn * sn
    return a, c, e, bx, by, cost


def _degenerate(a: float, c: float, e: float) -> bool:
    det = a * e - c * c
    return not det > (a + e) * (a + e) / MAX_CONDITION


def difference_geometry(xy, ref_xy, others_xy, height: float) -> tuple[np.ndarray, np.ndarray]:
    """Expected differences (k,) [m] and their x-y Jacobian D (k, 2) at ``xy``."""
    bxy = np.vstack([np.reshape(ref_xy, (1, 2)), np.reshape(others_xy, (-1, 2))])
    d = np.asarray(xy, dtype=float).reshape(1, 2) - bxy
    r = np.sqrt(np.sum(d * d, axis=1) + height * height)
    g = d / np.maximum(r, 1e-12)[:, None]
    return r[1:] - r[0], g[1:] - g[:1]


def fix_covariance(xy, ref_xy, others_xy, height: float, s: float) -> np.ndarray:
    """``s^2 (D^T C^-1 D)^-1`` (2, 2) [m^2] at ``xy``; TrilaterationError when singular."""
    oth = [(float(p[0]), float(p[1])) for p in np.reshape(others_xy, (-1, 2))]
    bxy = [(float(ref_xy[0]), float(ref_xy[1])), *oth]
    a, c, e, _, _, _ = _normal(float(xy[0]), float(xy[1]), [0.0] * len(oth), bxy, height)
    if _degenerate(a, c, e):
        raise TrilaterationError(f"the beacons' geometry does not fix the position at "
                                 f"({xy[0]:.3g}, {xy[1]:.3g}) (collinear beacons seen from their line?)")
    det = a * e - c * c
    return s * s * np.array([[e / det, -c / det], [-c / det, a / det]])


def trilaterate(diffs, ref_xy, others_xy, height: float, s: float) -> Fix:
    """The position fix from range differences ``diffs`` (k,) [m] of beacons ``others_xy``
    (k, 2) against the beacon at ``ref_xy`` (2,), all ``height`` above the receiver, each
    arrival of noise ``s`` [m] (module docstring for the method and the errors). Python
    floats throughout: the same fix on every machine (the simulation may call it)."""
    z = [float(v) for v in np.asarray(diffs, dtype=float).reshape(-1)]
    oth = [(float(p[0]), float(p[1])) for p in np.asarray(others_xy, dtype=float).reshape(-1, 2)]
    ref = (float(np.ravel(ref_xy)[0]), float(np.ravel(ref_xy)[1]))
    k = len(z)
    if k < 2 or len(oth) != k:
        raise TrilaterationError(f"{k} range difference(s) for {len(oth)} beacon(s): expected "
                                 f"at least 2 (three beacons) for a 2-D fix")
    if not (all(math.isfinite(v) for v in z) and math.isfinite(height) and s > 0):
        raise TrilaterationError("range differences, height and noise must be finite (noise > 0)")
    bxy = [ref, *oth]
    cx = sum(p[0] for p in bxy) / (k + 1)
    cy = sum(p[1] for p in bxy) / (k + 1)
    spread = max(math.hypot(p[0] - cx, p[1] - cy) for p in bxy)
    if spread < 1e-6:
        raise TrilaterationError("the beacons are all at one point: no fix")
    reach = max(3.0 * spread, 1.0 + max(abs(v) for v in z))
    starts = [(cx, cy)] + [(cx + reach * c, cy + reach * sn) for c, sn in _COMPASS]
    found: list[tuple[float, float, float]] = []
    for x, y in starts:
        for _ in range(MAX_STEPS):
            a, c, e, bx, by, _ = _normal(x, y, z, bxy, height)
            if _degenerate(a, c, e):
                break
            det = a * e - c * c
            sx, sy = (e * bx - c * by) / det, (a * by - c * bx) / det
            x, y = x + sx, y + sy
            if math.hypot(sx, sy) < TOL_M:
                cost = _normal(x, y, z, bxy, height)[5] / (s * s)
                found.append((cost, x, y))
                break
    if not found:
        raise TrilaterationError("Gauss-Newton did not converge from any start: the geometry "
                                 "does not fix the position")
    found.sort()
    cost, x0, y0 = found[0]
    for c1, x1, y1 in found[1:]:
        if c1 - cost < AMBIGUOUS_COST and math.hypot(x1 - x0, y1 - y0) > AMBIGUOUS_M:
            raise TrilaterationError(f"ambiguous fix: ({x0:.3g}, {y0:.3g}) and ({x1:.3g}, {y1:.3g}) "
                                     f"explain the differences alike")
    cov = fix_covariance((x0, y0), ref, oth, height, s)
    return Fix(xy=np.array([x0, y0]), cov=cov, hdop=math.sqrt(cov[0, 0] + cov[1, 1]) / s, cost=cost)


#: Unit vectors to the eight extra starts (exact values: no libm at run time).
_R2 = math.sqrt(0.5)
_COMPASS = ((1.0, 0.0), (_R2, _R2), (0.0, 1.0), (-_R2, _R2), (-1.0, 0.0), (-_R2, -_R2),
            (0.0, -1.0), (_R2, -_R2))


def tdoa_hdop(xy, bxy, height: float) -> np.ndarray:
    """HDOP (N,) of a TDOA fix at points ``xy`` (N, 2) from all beacons ``bxy`` (n, 2):
    ``sqrt(trace((G^T (I - 1 1^T / n) G)^-1))`` with G the unit vectors' x-y parts (the same
    for every reference); inf where the geometry does not fix the position. For the window's
    floor shading."""
    p = np.asarray(xy, dtype=float).reshape(-1, 2)
    b = np.asarray(bxy, dtype=float).reshape(-1, 2)
    d = p[:, None, :] - b[None]
    r = np.sqrt(np.sum(d * d, axis=2) + height * height)
    g = d / np.maximum(r, 1e-12)[..., None]
    s1 = g.sum(axis=1)
    S2 = np.einsum("nbi,nbj->nij", g, g) - np.einsum("ni,nj->nij", s1, s1) / b.shape[0]
    a, c, e = S2[:, 0, 0], S2[:, 0, 1], S2[:, 1, 1]
    det = a * e - c * c
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(det > 1e-12 * np.maximum(a + e, 1e-300) ** 2, np.sqrt((a + e) / det), np.inf)


__all__ = ["Fix", "TrilaterationError", "difference_geometry", "fix_covariance", "tdoa_hdop",
           "trilaterate"]
