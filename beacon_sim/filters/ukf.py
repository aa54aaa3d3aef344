"""Unscented Kalman filter (seed 000 eq. 11-15 and its UKF steps; seed 001's alpha/beta/kappa).

Sigma points of the n = 3 state::

    X_0 = m,  X_i = m + (sqrt(c P))_i,  X_{n+i} = m - (sqrt(c P))_i,   i = 1..n

``scaled = True`` (seed 001): lambda = alpha^2 (n + kappa) - n, c = n + lambda,
Wm_0 = lambda / c, Wc_0 = Wm_0 + 1 - alpha^2 + beta, W_i = 1 / (2 c).
``scaled = False`` (seed 000 eq. 13): c = n + kappa, W_0 = kappa / c, W_i = 1 / (2 c) for
both mean and covariance (the scaled form with alpha = 1, beta = 0).

Prediction: the sigma points go through the velocity model; the mean is the weighted mean
(the heading a *circular* weighted mean), the covariance the weighted outer products of the
residuals (heading residual wrapped) plus Q. Update (seed 000): new sigma points are drawn
from the predicted belief, passed through the stacked measurement model of all the tick's
readings; angle rows use circular means and wrapped residuals::

    S = sum Wc dZ dZ^T + R,   Pxz = sum Wc dX dZ^T,   K = Pxz S^-1
    m = m + K wrap(z - z_hat),  P = P - K S K^T (symmetrised)

The square root is a Cholesky factor; when P is near-singular it retries with a small
diagonal jitter, and finally uses the eigen-decomposition with negative eigenvalues
clipped to zero, so a degenerate covariance never stops the filter.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import ClassVar

import numpy as np

from beacon_sim.core.types import Control, Measurement
from beacon_sim.filters.base import (
    FilterBase,
    FilterContext,
    FilterError,
    GaussianBelief,
    broad_gaussian,
)
from beacon_sim.filters.gaussian_measurements import ReadingModels, process_cov_terms, stack

N = 3
_PI = np.pi
_TWO_PI = 2.0 * np.pi


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


def sigma_weights(alpha: float, beta: float, kappa: float, scaled: bool, n: int = N):
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


class UnscentedKalmanFilter(FilterBase):
    """UKF over ``[x, y, theta]`` for bearing, range-bearing, pose and position readings.

    Parameters (``ctx.params``)
    ---------------------------
    alpha : float, default 1.0
        Spread of the sigma points (scaled form only).
    beta : float, default 2.0
        Prior-knowledge term of Wc_0; 2 is optimal for a Gaussian (scaled form only).
    kappa : float, default 0.0
        Secondary spread; with ``scaled = False`` seed 000's kappa (n + kappa = 3 here).
    scaled : bool, default True
        True: the alpha/beta/kappa form (seed 001); False: seed 000's kappa-only form.
    gate_chi2 : float, default 0.0
        0 turns gating off; otherwise a beacon's reading (or a whole fix) is dropped when its
        squared Mahalanobis distance ``nu_b^T S_bb^-1 nu_b`` exceeds this (as the EKF's).
    """

    defaults: ClassVar[dict] = {"alpha": 1.0, "beta": 2.0, "kappa": 0.0, "scaled": True,
                                "gate_chi2": 0.0}
    sensor_kinds: ClassVar[tuple[str, ...]] = ("bearing", "range_bearing", "pose", "position")

    def __init__(self, ctx: FilterContext):
        super().__init__(ctx)
        p = self.params
        self.c, self.Wm, self.Wc = sigma_weights(p["alpha"], p["beta"], p["kappa"], p["scaled"])
        self.sqrt_c = math.sqrt(self.c)
        self._wm, self._wc = self.Wm.tolist(), self.Wc.tolist()
        self.models = ReadingModels(ctx)
        self.gate = float(p["gate_chi2"])
        self.rejected = 0  # readings dropped by the gate so far
        self.reset(None)

    def reset(self, initial: GaussianBelief | None) -> None:
        initial = initial or broad_gaussian(self.ctx.world)
        self.mean = np.array(initial.mean, dtype=float)
        self.mean[2] = (self.mean[2] + _PI) % _TWO_PI - _PI
        cov = np.array(initial.cov, dtype=float)
        self.cov = 0.5 * (cov + cov.T)

    def estimate(self) -> tuple[np.ndarray, np.ndarray]:
        return self.mean.copy(), self.cov.copy()

    def _offsets(self) -> list[tuple[float, float, float]]:
        """The 2n + 1 sigma-point offsets from the mean: 0, +- columns of sqrt(c P).

        The 3x3 Cholesky factor is written out on floats (a numpy call costs ~1 us,
        design.md section 9); ``robust_sqrt`` takes over when a pivot is not positive."""
        (a00, a01, a02), (_, a11, a12), (_, _, a22) = self.cov.tolist()
        sc = self.sqrt_c
        try:
            l00 = math.sqrt(a00)
            l10 = a01 / l00
            l20 = a02 / l00
            l11 = math.sqrt(a11 - l10 * l10)
            l21 = (a12 - l20 * l10) / l11
            l22 = math.sqrt(a22 - l20 * l20 - l21 * l21)
            cols = ((sc * l00, sc * l10, sc * l20), (0.0, sc * l11, sc * l21), (0.0, 0.0, sc * l22))
        except (ValueError, ZeroDivisionError):
            L = robust_sqrt(self.cov) * sc
            cols = tuple(tuple(c) for c in L.T.tolist())
        return [(0.0, 0.0, 0.0), *cols, *((-a, -b, -c) for a, b, c in cols)]

    def _sigma_points(self) -> np.ndarray:
        """Sigma points, shape (7, 3): the mean plus the offsets (heading not wrapped)."""
        return self.mean + np.array(self._offsets())

    def predict(self, control: Control, dt: float) -> None:
        v, w = float(control.v), float(control.omega)
        m0, m1, m2 = self.mean.tolist()
        vdt, wdt = v * dt, w * dt
        Wm, Wc = self._wm, self._wc
        cw, sw = math.cos(wdt), math.sin(wdt)
        # The velocity model on every sigma point; weighted sums for the mean as we go.
        Y = []
        x = y = sn = cs = 0.0
        for wi, (d0, d1, d2) in zip(Wm, self._offsets(), strict=True):
            th = m2 + d2
            c, s = math.cos(th), math.sin(th)
            a, b = m0 + d0 + vdt * c, m1 + d1 + vdt * s
            th += wdt
            Y.append((a, b, th))
            x += wi * a
            y += wi * b
            # sin and cos of th + wdt from those of th (angle addition)
            sn += wi * (s * cw + c * sw)
            cs += wi * (c * cw - s * sw)
        th = math.atan2(sn, cs)                 # circular weighted mean of the heading
        # P = sum Wc d d^T + Q with the heading residual wrapped.
        q00, q01, q02, q11, q12, q22 = process_cov_terms(self.ctx.motion_noise, m2, v, w, dt)
        for wi, (a, b, c) in zip(Wc, Y, strict=True):
            da, db = a - x, b - y
            dc = (c - th + _PI) % _TWO_PI - _PI
            wa, wb, wc = wi * da, wi * db, wi * dc
            q00 += wa * da
            q01 += wa * db
            q02 += wa * dc
            q11 += wb * db
            q12 += wb * dc
            q22 += wc * dc
        self.mean = np.array([x, y, (th + _PI) % _TWO_PI - _PI])
        self.cov = np.array([[q00, q01, q02], [q01, q11, q12], [q02, q12, q22]])

    def update(self, measurements: Sequence[Measurement]) -> None:
        if not measurements:
            return
        st = stack(self.models, measurements)
        if st is None:
            return
        D = np.array(self._offsets())             # redrawn from the predicted belief (seed 000)
        Z = st.predict(self.mean + D, wrap=False)  # (7, m); residuals are wrapped below
        Wm, Wc = self.Wm, self.Wc
        sel = st.angle_sel
        zhat = Wm @ Z
        if sel is not None:                       # circular means of the angle rows
            Za = Z[:, sel]
            zhat[sel] = np.arctan2(Wm @ np.sin(Za), Wm @ np.cos(Za))
        dZ = Z - zhat
        nu = st.z - zhat
        if sel is not None:                       # wrapped residuals
            dZ[:, sel] = (dZ[:, sel] + _PI) % _TWO_PI - _PI
            nu[sel] = (nu[sel] + _PI) % _TWO_PI - _PI
        WdZ = dZ * Wc[:, None]
        S = dZ.T @ WdZ
        S.flat[:: S.shape[0] + 1] += st.r         # + R (diagonal)
        Pxz = D.T @ WdZ                           # sum Wc dX dZ^T, dX = the sigma offsets
        if self.gate > 0.0:
            keep = self._gate(st, S, nu)
            if keep is not None:
                if not keep.any():
                    return
                S, Pxz, nu = S[np.ix_(keep, keep)], Pxz[:, keep], nu[keep]
        Kt = _solve(S, Pxz.T)                     # K^T = S^-1 Pxz^T (S symmetric)
        m = self.mean + nu @ Kt
        m[2] = (m[2] + _PI) % _TWO_PI - _PI
        P = self.cov - Pxz @ Kt                   # P - K S K^T = P - Pxz K^T
        P += P.T
        P *= 0.5
        self.cov = P
        self.mean = m

    def _gate(self, st, S: np.ndarray, nu: np.ndarray) -> np.ndarray | None:
        """Rows to keep (bool mask), or None when every reading passes the chi-square gate.

        A beacon's rows (1 for a bearing, 2 for range-bearing) or a fix's rows are tested
        together against their block of S."""
        keep = np.ones(nu.shape[0], dtype=bool)
        for kind, a, b, _ in st.blocks:
            width = 1 if kind == "bearing" else 2 if kind == "range_bearing" else b - a
            for i in range(a, b, width):
                j = i + width
                d2 = float(nu[i:j] @ np.linalg.solve(S[i:j, i:j], nu[i:j]))
                if d2 > self.gate:
                    keep[i:j] = False
                    self.rejected += 1
        return None if keep.all() else keep


def _solve(S: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``S^-1 B`` for a small symmetric positive-definite S. numpy's solve spends ~10 us in
    its Python wrapper on a 4x4 system; the gufunc underneath takes ~3 us."""
    if _gufunc_solve is not None:
        X = _gufunc_solve(S, B)
        if np.isfinite(X).all():
            return X
    return np.linalg.solve(S, B)  # raises LinAlgError for a singular S


try:  # the ufunc np.linalg.solve wraps (numpy >= 1.8); absent: use the public function
    from numpy.linalg import _umath_linalg as _ul

    _gufunc_solve = _ul.solve
except (ImportError, AttributeError):  # pragma: no cover
    _gufunc_solve = None
