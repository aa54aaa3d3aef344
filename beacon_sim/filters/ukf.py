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
    """

    defaults: ClassVar[dict] = {"alpha": 1.0, "beta": 2.0, "kappa": 0.0, "scaled": True}
    sensor_kinds: ClassVar[tuple[str, ...]] = ("bearing", "range_bearing", "pose", "position")

    def __init__(self, ctx: FilterContext):
        super().__init__(ctx)
        p = self.params
        self.c, self.Wm, self.Wc = sigma_weights(p["alpha"], p["beta"], p["kappa"], p["scaled"])
        self.sqrt_c = float(np.sqrt(self.c))
        self.models = ReadingModels(ctx)
        self._X = np.empty((2 * N + 1, N))   # sigma points
        self._D = np.zeros((2 * N + 1, N))   # their offsets from the mean
        self.reset(None)

    def reset(self, initial: GaussianBelief | None) -> None:
        initial = initial or broad_gaussian(self.ctx.world)
        self.mean = np.array(initial.mean, dtype=float)
        self.mean[2] = (self.mean[2] + _PI) % _TWO_PI - _PI
        cov = np.array(initial.cov, dtype=float)
        self.cov = 0.5 * (cov + cov.T)

    def estimate(self) -> tuple[np.ndarray, np.ndarray]:
        return self.mean.copy(), self.cov.copy()

    def _sigma_points(self) -> np.ndarray:
        """Fill ``_X`` (7, 3) and ``_D`` (offsets, unwrapped) from the current belief."""
        L = robust_sqrt(self.cov)
        D = self._D
        D[1:N + 1] = L.T
        D[1:N + 1] *= self.sqrt_c
        D[N + 1:] = -D[1:N + 1]
        np.add(D, self.mean, out=self._X)
        return self._X

    def predict(self, control: Control, dt: float) -> None:
        v, w = float(control.v), float(control.omega)
        X = self._sigma_points()
        th = X[:, 2]
        Y = X.copy()
        Y[:, 0] += v * dt * np.cos(th)          # the velocity model on every sigma point
        Y[:, 1] += v * dt * np.sin(th)
        Y[:, 2] += w * dt
        Wm = self.Wm
        m = Wm @ Y                                # weighted mean (x, y)
        m[2] = np.arctan2(Wm @ np.sin(Y[:, 2]), Wm @ np.cos(Y[:, 2]))  # circular mean
        D = Y - m
        D[:, 2] = (D[:, 2] + _PI) % _TWO_PI - _PI  # wrapped heading residuals
        q00, q01, q02, q11, q12, q22 = process_cov_terms(
            self.ctx.motion_noise, float(self.mean[2]), v, w, dt)
        Q = np.array([[q00, q01, q02], [q01, q11, q12], [q02, q12, q22]])
        self.cov = (D.T * self.Wc) @ D + Q
        self.mean = m

    def update(self, measurements: Sequence[Measurement]) -> None:
        if not measurements:
            return
        st = stack(self.models, measurements)
        if st is None:
            return
        X = self._sigma_points()                  # redrawn from the predicted belief (seed 000)
        Z = st.predict(X)                         # (7, m)
        Wm, Wc = self.Wm, self.Wc
        ang = st.angle
        zhat = Wm @ Z
        if ang.any():
            Za = Z[:, ang]
            zhat[ang] = np.arctan2(Wm @ np.sin(Za), Wm @ np.cos(Za))
        dZ = Z - zhat
        nu = st.z - zhat
        if ang.any():
            dZ[:, ang] = (dZ[:, ang] + _PI) % _TWO_PI - _PI
            nu[ang] = (nu[ang] + _PI) % _TWO_PI - _PI
        WdZ = dZ * Wc[:, None]
        S = dZ.T @ WdZ
        S[np.diag_indices_from(S)] += st.r
        Pxz = self._D.T @ WdZ                     # sum Wc dX dZ^T, dX = the sigma offsets
        Kt = np.linalg.solve(S, Pxz.T)           # K^T = S^-1 Pxz^T (S symmetric)
        m = self.mean + nu @ Kt
        m[2] = (m[2] + _PI) % _TWO_PI - _PI
        P = self.cov - Pxz @ Kt                   # P - K S K^T = P - Pxz K^T
        self.cov = 0.5 * (P + P.T)
        self.mean = m
