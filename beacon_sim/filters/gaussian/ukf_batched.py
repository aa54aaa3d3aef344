"""The UKF on R runs at once (:class:`BatchedUKF`, for ``evaluation.montecarlo``): the same
weights, Cholesky (:func:`~beacon_sim.filters.gaussian.unscented.cholesky3`) and update
(:func:`~beacon_sim.filters.gaussian.unscented.innovation`, ``correct``) as
:class:`~beacon_sim.filters.gaussian.ukf.UnscentedKalmanFilter`, on arrays with a leading run
axis; the prediction is the loop over sigma points written on arrays (R, 7, 3); the gate
(``unscented_gate``) tests each run's readings against its own S. States [m, m, rad]."""

from __future__ import annotations

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.motion import MotionNoise
from beacon_sim.filters.gaussian.measurements import (
    LOW_RANK_ROWS,
    BatchedGaussian,
    StackedReadings,
    add_diagonal,
    cov_entries,
    cov_matrix,
    process_cov_terms,
)
from beacon_sim.filters.gaussian.unscented import (
    cholesky3,
    correct,
    correct_low_rank,
    heading_limited_weights,
    innovation,
    innovation_parts,
    robust_sqrt,
    unscented_gate,
)


class BatchedUKF(BatchedGaussian):
    """The UKF for R runs, with its gate (``gate`` > 0: :func:`unscented_gate`; a failed
    reading's residuals and innovation are set to 0, so its rows of S are R alone and it
    changes nothing, as when the per-run filter drops it)."""

    def __init__(self, mean0: np.ndarray, cov0: np.ndarray, runs: int, noise: MotionNoise,
                 sqrt_c: float, Wm: np.ndarray, Wc: np.ndarray, gate: float = 0.0):
        super().__init__(mean0, cov0, runs, noise)
        self.sqrt_c, self.Wm, self.Wc = sqrt_c, Wm, Wc
        self.Wm_now, self.Wc_now = Wm, Wc              # the weights of the last offsets()
        self.gate = float(gate)
        self.rejected = np.zeros(runs, dtype=np.int64)  # readings dropped by the gate, per run

    def offsets(self) -> np.ndarray:
        """Sigma-point offsets (R, 7, 3): 0, +- the columns of sqrt(c P) (:func:`cholesky3`;
        ``robust_sqrt`` for the runs where a pivot is not positive)."""
        P = self.cov
        a = cov_entries(P)
        (l00, l10, l20, l11, l21, l22), (p1, p2) = cholesky3(*a, np.sqrt)
        L = np.zeros_like(P)
        L[:, 0, 0], L[:, 1, 0], L[:, 2, 0] = l00, l10, l20
        L[:, 1, 1], L[:, 2, 1] = l11, l21
        L[:, 2, 2] = l22
        for i in np.flatnonzero((a[0] <= 0.0) | (p1 <= 0.0) | (p2 < 0.0)):
            L[i] = robust_sqrt(P[i])
        sc, self.Wm_now, self.Wc_now = heading_limited_weights(self.sqrt_c ** 2, self.Wm, self.Wc,
                                                               P[:, 2, 2])
        if np.all(sc == self.sqrt_c):                  # no run needs a limited spread
            sc, self.Wm_now, self.Wc_now = self.sqrt_c, self.Wm, self.Wc
        else:
            sc = sc[:, None, None]
        cols = sc * L.swapaxes(-1, -2)                 # row j = column j of sqrt(c P)
        return np.concatenate([np.zeros((len(P), 1, 3)), cols, -cols], axis=1)

    def predict(self, v: np.ndarray, w: np.ndarray, dt: float) -> None:
        """The UKF's ``predict`` with every sum over sigma points on arrays."""
        D = self.offsets()
        m = self.mean
        X = m[:, None, :] + D                           # sigma points, heading not wrapped
        vdt = (v * dt)[:, None]
        wdt = (w * dt)[:, None]
        th = X[..., 2]
        c, s = np.cos(th), np.sin(th)
        a = X[..., 0] + vdt * c
        b = X[..., 1] + vdt * s
        cw, sw = np.cos(wdt), np.sin(wdt)
        Wm, Wc = self.Wm_now, self.Wc_now             # (7,) or per run (R, 7)
        x = np.sum(a * Wm, axis=1)
        y = np.sum(b * Wm, axis=1)
        sn = np.sum((s * cw + c * sw) * Wm, axis=1)
        cs = np.sum((c * cw - s * sw) * Wm, axis=1)
        thm = np.arctan2(sn, cs)                        # circular weighted mean
        if Wm.ndim > 1:                                 # limited spread in some runs
            lim = Wm[:, 0] < 0.0
            thm = np.where(lim, m[:, 2] + wdt[:, 0], thm)
        dX = np.empty_like(X)                           # residuals, heading wrapped
        dX[..., 0], dX[..., 1], dX[..., 2] = a - x[:, None], b - y[:, None], wrap(th + wdt - thm[:, None])
        th0 = m[:, 2]
        Q = cov_matrix(process_cov_terms(self.noise, th0, np.cos(th0), np.sin(th0), v, w, dt))
        self.cov = (dX * Wc[..., None]).swapaxes(-1, -2) @ dX + Q
        mean = np.empty_like(m)
        mean[:, 0], mean[:, 1], mean[:, 2] = x, y, wrap(thm)
        self.mean = mean

    def update(self, st: StackedReadings) -> None:
        D = self.offsets()
        X = self.mean[:, None, :] + D                   # (R, 7, 3)
        R, n, _ = X.shape
        Z = st.predict(X.reshape(R * n, 3), wrap=False).reshape(R, n, -1)
        if st.valid is not None:                        # empty slots: no reading, no residual
            Z = np.where(st.valid[:, None, :], Z, 0.0)
        if self.gate > 0.0:
            self._update_gated(st, Z, D)
            return
        if Z.shape[-1] > LOW_RANK_ROWS:                 # many slots: linear in them
            dZ, _, Pxz, nu = innovation_parts(Z, D, st.z, st.angle_sel, self.Wm_now, self.Wc_now)
            self.mean, self.cov = correct_low_rank(self.mean, self.cov, dZ, self.Wc_now, st.r, Pxz, nu,
                                                   strict=False)
            return
        S, Pxz, nu = innovation(Z, D, st.z, st.r, st.angle_sel, self.Wm_now, self.Wc_now)
        self.mean, self.cov = correct(self.mean, self.cov, S, Pxz, nu, strict=False)

    def _update_gated(self, st: StackedReadings, Z: np.ndarray, D: np.ndarray) -> None:
        """:meth:`update` with the gate: the readings that fail :func:`unscented_gate` get
        zero residuals, cross-covariance and innovation before the update."""
        dZ, WdZ, Pxz, nu = innovation_parts(Z, D, st.z, st.angle_sel, self.Wm_now, self.Wc_now)
        r = np.broadcast_to(st.r, nu.shape)
        keep, dropped = unscented_gate(st, dZ, self.Wc_now, r, nu, self.gate)
        self.rejected += dropped
        if not keep.all():
            k = keep[:, None, :]
            dZ, WdZ, Pxz, nu = (np.where(k, dZ, 0.0), np.where(k, WdZ, 0.0), np.where(k, Pxz, 0.0),
                                np.where(keep, nu, 0.0))
        if Z.shape[-1] > LOW_RANK_ROWS:
            self.mean, self.cov = correct_low_rank(self.mean, self.cov, dZ, self.Wc_now, st.r, Pxz, nu,
                                                   strict=False)
            return
        S = dZ.swapaxes(-1, -2) @ WdZ
        add_diagonal(S, r)
        self.mean, self.cov = correct(self.mean, self.cov, S, Pxz, nu, strict=False)


__all__ = ["BatchedUKF"]
