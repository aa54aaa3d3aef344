"""The unscented transform of the UKF (seed 000 eq. 11-15; seed 001's alpha, beta, kappa), for
one run or R runs on arrays: the sigma weights (and their heading-limited form), the square
root of P (Cholesky, jitter, clipped eigen-decomposition; a 3x3 Cholesky on arrays), the
innovation with circular means on the angle rows, the Kalman correction (direct and low-rank)
and the per-reading gate on R runs. Poses [m, m, rad], world frame."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.filters.base import FilterError
from beacon_sim.filters.gaussian.measurements import (
    ALL_ROWS,
    AngleRows,
    StackedReadings,
    add_diagonal,
    corrected_mean,
    gate_blocks,
    solve,
    symmetrise,
)

N = 3


def robust_sqrt(A: np.ndarray) -> np.ndarray:
    """A lower factor L with ``L L^T = A`` (symmetric A), for near-singular A too.

    Cholesky; on failure Cholesky of ``A + eps I`` with eps = 1e-12, 1e-9, 1e-6 times the
    mean diagonal; last, ``V sqrt(max(w, 0))`` from the eigen-decomposition.
    """
    try:
        return np.linalg.cholesky(A)
    except np.linalg.LinAlgError:
        pass
    A = 0.5 * (A + A.T)
    scale = max(float(np.trace(A)) / A.shape[0], 1e-300)
    eye = np.eye(A.shape[0])
    for eps in (1e-12, 1e-9, 1e-6):
        try:
            return np.linalg.cholesky(A + eps * scale * eye)
        except np.linalg.LinAlgError:
            continue
    w, V = np.linalg.eigh(A)
    return V * np.sqrt(np.clip(w, 0.0, None))


def cholesky3(a00: Any, a01: Any, a02: Any, a11: Any, a12: Any, a22: Any,
              sqrt: Callable[[Any], Any]) -> tuple[tuple[Any, ...], tuple[Any, Any]]:
    """The lower Cholesky factor of a symmetric 3x3 matrix from its six distinct entries,
    on floats (``sqrt = math.sqrt``: ValueError or ZeroDivisionError when a pivot is not
    positive) or arrays (R,) (``sqrt = np.sqrt``: NaN or inf there).

    Returns ``(l00, l10, l20, l11, l21, l22)`` and the pivots ``(p1, p2)`` = l11^2, l22^2.
    """
    l00 = sqrt(a00)
    l10 = a01 / l00
    l20 = a02 / l00
    p1 = a11 - l10 * l10
    l11 = sqrt(p1)
    l21 = (a12 - l20 * l10) / l11
    p2 = a22 - l20 * l20 - l21 * l21
    return (l00, l10, l20, l11, l21, sqrt(p2)), (p1, p2)


def sigma_weights(alpha: float, beta: float, kappa: float, scaled: bool, n: int = N
                  ) -> tuple[float, np.ndarray, np.ndarray]:
    """``(c, Wm, Wc)``: the spread factor c (points at m +- columns of sqrt(c P)) and the
    mean and covariance weights, shape (2n + 1,)."""
    if scaled:
        lam = alpha * alpha * (n + kappa) - n
        c = n + lam
    else:
        lam = kappa
        c = n + kappa
    if not c > 0:
        raise FilterError(f"ukf: n + lambda = {c:g} must be > 0 (raise kappa or alpha)")
    Wm = np.full(2 * n + 1, 0.5 / c)
    Wc = Wm.copy()
    Wm[0] = lam / c
    Wc[0] = lam / c + ((1.0 - alpha * alpha + beta) if scaled else 0.0)
    return c, Wm, Wc


#: Largest heading offset [rad] of a sigma point from the mean. Beyond pi/2 the + and -
#: points approach each other around the circle (at pi they coincide, which the default
#: c = 3 reaches for a room-wide heading, std pi / sqrt(3)), and the wrapped residuals no
#: longer carry the spread.
MAX_HEADING_OFFSET = 0.5 * math.pi


def heading_limited_weights(c: float, Wm: np.ndarray, Wc: np.ndarray, p_thth
                            ) -> tuple[Any, np.ndarray, np.ndarray]:
    """Spread and weights for a belief with heading variance ``p_thth`` [rad^2] (a float, or
    an array (R,) for R runs): ``c`` unchanged while ``sqrt(c p_thth) <= MAX_HEADING_OFFSET``,
    else ``c' = MAX_HEADING_OFFSET^2 / p_thth`` with ``W_i = 1 / (2 c')``,
    ``Wm_0 = 1 - n / c'`` (the weights still sum to one and reproduce the mean and covariance)
    and ``Wc_0`` keeping the configured ``Wc_0 - Wm_0`` (beta) term.

    Returns ``(sqrt_c, Wm, Wc)``: shapes (), (2n + 1,) or (R,), (R, 2n + 1)."""
    limit2 = MAX_HEADING_OFFSET * MAX_HEADING_OFFSET
    if type(p_thth) is float and not c * p_thth > limit2:  # one run, not limited: no numpy
        return math.sqrt(c), Wm, Wc                          # (~4 us a call on the hot path)
    pt = np.asarray(p_thth, dtype=float)
    with np.errstate(divide="ignore"):
        ceff = np.where(c * pt > limit2, limit2 / np.maximum(pt, 1e-300), c)
    if pt.ndim == 0 and float(ceff) == c:
        return math.sqrt(c), Wm, Wc
    n = (Wm.shape[-1] - 1) // 2
    wi = 0.5 / ceff
    Wm2 = np.broadcast_to(wi[..., None], (*np.shape(ceff), 2 * n + 1)).copy()
    Wm2[..., 0] = 1.0 - n / ceff
    Wc2 = Wm2.copy()
    # Wm_0 < 0 once c' < n; a negative Wc_0 could make the covariance indefinite, and it
    # multiplies a zero residual in the linear case, so it is clipped at zero.
    Wc2[..., 0] = np.maximum(Wc2[..., 0] + (Wc[0] - Wm[0]), 0.0)
    return (math.sqrt(float(ceff)) if pt.ndim == 0 else np.sqrt(ceff)), Wm2, Wc2


def innovation(Z: np.ndarray, D: np.ndarray, z: np.ndarray, r: np.ndarray, sel: AngleRows,
               Wm: np.ndarray, Wc: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The unscented innovation of one run (Z (7, m) the readings expected at the sigma
    points, D (7, 3) their offsets, z, r (m,)) or of R runs (a leading axis R on each).

    Returns S = sum Wc dZ dZ^T + diag(r) (..., m, m), Pxz = sum Wc dX dZ^T (..., 3, m) and
    nu = z - z_hat (..., m); the angle rows ``sel`` use circular means and wrapped residuals.
    """
    dZ, WdZ, Pxz, nu = innovation_parts(Z, D, z, sel, Wm, Wc)
    S = dZ.swapaxes(-1, -2) @ WdZ
    add_diagonal(S, r)
    return S, Pxz, nu


def innovation_parts(Z: np.ndarray, D: np.ndarray, z: np.ndarray, sel: AngleRows, Wm: np.ndarray,
                     Wc: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`innovation` before S is formed: the residuals dZ (..., 7, m), Wc dZ, Pxz and
    nu; linear in the readings (:func:`correct_low_rank` goes on from here)."""
    if Wm.ndim == 1:
        def wsum(A: np.ndarray) -> np.ndarray:
            return Wm @ A
    else:                                               # weights per run (R, 7)
        def wsum(A: np.ndarray) -> np.ndarray:
            return np.einsum("...i,...ij->...j", Wm, A)
    limited = Wm[..., 0] < 0.0                         # () or per run (R,)
    any_limited = bool(limited) if Wm.ndim == 1 else bool(limited.any())  # any(): ~2 us on a scalar

    def angle_mean(A: np.ndarray) -> np.ndarray:
        circ = np.arctan2(wsum(np.sin(A)), wsum(np.cos(A)))  # circular weighted mean
        if not any_limited:
            return circ
        # A negative centre weight breaks the circular mean: average the residuals about
        # the centre point instead (the sigma points lie within pi/2 of it).
        A0 = A[..., :1, :]
        rel = A0[..., 0, :] + wsum(wrap(A - A0))
        return np.where(np.reshape(limited, (*np.shape(limited), 1)), rel, circ)

    if sel is ALL_ROWS:
        zhat = angle_mean(Z)
    else:
        zhat = wsum(Z)
        if sel is not None:
            zhat[..., sel] = angle_mean(Z[..., sel])
    # The residuals of the sigma points (rows 0..2n) and of the measurement (last row),
    # angle rows wrapped in one call.
    dY = np.empty((*Z.shape[:-2], Z.shape[-2] + 1, Z.shape[-1]))
    np.subtract(Z, zhat[..., None, :], out=dY[..., :-1, :])
    np.subtract(z, zhat, out=dY[..., -1, :])
    if sel is not None:
        dY[..., sel] = wrap(dY[..., sel])
    dZ, nu = dY[..., :-1, :], dY[..., -1, :]
    WdZ = dZ * Wc[..., None]
    Pxz = D.swapaxes(-1, -2) @ WdZ                     # dX = the sigma offsets
    return dZ, WdZ, Pxz, nu


def correct(mean: np.ndarray, P: np.ndarray, S: np.ndarray, Pxz: np.ndarray, nu: np.ndarray,
            strict: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """``K = Pxz S^-1``, ``mean + K nu`` (heading wrapped), ``P - K S K^T = P - Pxz K^T``
    (symmetrised), for one run or R runs; ``strict``: see ``measurements.solve``."""
    Kt = solve(S, Pxz.swapaxes(-1, -2), strict)        # K^T = S^-1 Pxz^T (S symmetric)
    return corrected_mean(mean, Kt, nu), symmetrise(P - Pxz @ Kt)


def correct_low_rank(mean: np.ndarray, P: np.ndarray, dZ: np.ndarray, Wc: np.ndarray, r: np.ndarray,
                     Pxz: np.ndarray, nu: np.ndarray, strict: bool = True
                     ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`correct` without forming S = dZ^T W dZ + R (m x m, W = diag(Wc), R = diag(r):
    independent readings), linear in the readings m. Woodbury, in the form that never
    inverts W (a weight may be zero)::

        S^-1 = R^-1 - R^-1 dZ^T (I + W G)^-1 W dZ R^-1,   G = dZ R^-1 dZ^T (7 x 7)

    I + W G is invertible for W >= 0. One run (dZ (7, m)) or R runs (a leading axis)."""
    Ar = dZ / r[..., None, :]                          # dZ R^-1 (..., 7, m)
    G = Ar @ dZ.swapaxes(-1, -2)                       # (..., 7, 7)
    Wcol = Wc[..., :, None]
    B = Pxz.swapaxes(-1, -2) / r[..., :, None]         # R^-1 Pxz^T (..., m, 3)
    Y = solve(np.eye(G.shape[-1]) + Wcol * G, Wcol * (dZ @ B), strict)   # (..., 7, 3)
    Kt = B - Ar.swapaxes(-1, -2) @ Y                   # K^T = S^-1 Pxz^T (..., m, 3)
    return corrected_mean(mean, Kt, nu), symmetrise(P - Pxz @ Kt)


def unscented_gate(st: StackedReadings, dZ: np.ndarray, Wc: np.ndarray, r: np.ndarray, nu: np.ndarray,
                   gate: float) -> tuple[np.ndarray, np.ndarray]:
    """The per-run UKF's gate on R runs at once: each beacon's reading (range and bearing
    together) or fix whose squared Mahalanobis distance ``nu_b^T S_bb^-1 nu_b`` exceeds
    ``gate``, with ``S_bb = sum_k Wc_k dZ_kb dZ_kb^T + R_bb`` its block of the unscented S
    (the sigma points of the predicted belief), fails. ``dZ`` (R, 7, M) the residuals of the
    expected readings, ``Wc`` (7,) or (R, 7), ``r`` and ``nu`` (R, M) as
    :func:`innovation_parts` gives them; empty slots pass (their residuals are 0).

    Returns ``(keep, rejected)``: ``keep`` (R, M) bool, False on the rows of failed
    readings, and ``rejected`` (R,) the readings that failed, per run."""
    R = nu.shape[0]
    W = np.broadcast_to(Wc, (R, dZ.shape[-2]))

    def unscented(a: int, b: int, width: int) -> np.ndarray:
        d = dZ[:, :, a:b].reshape(R, dZ.shape[-2], -1, width)        # (R, 7, G, width)
        return np.einsum("rk,rkgi,rkgj->rgij", W, d, d)

    return gate_blocks(st, nu, r, gate, unscented)


__all__ = ["MAX_HEADING_OFFSET", "N", "cholesky3", "correct", "correct_low_rank",
           "heading_limited_weights", "innovation", "innovation_parts", "robust_sqrt",
           "sigma_weights", "unscented_gate"]
