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

R runs at once: :class:`~beacon_sim.filters.gaussian.ukf_batched.BatchedUKF` (``ukf_batched.py``,
re-exported here).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any, ClassVar

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.types import Control, Measurement
from beacon_sim.filters import association
from beacon_sim.filters.base import FilterContext, GaussianBelief, broad_gaussian
from beacon_sim.filters.gaussian.measurements import (
    FIX_KINDS,
    LOW_RANK_ROWS,
    BatchableFilter,
    ReadingModels,
    StackedReadings,
    add_diagonal,
    effective_gate,
    model_readings,
    process_cov_terms,
    solve,
    stack,
)
from beacon_sim.filters.gaussian.ukf_batched import BatchedUKF
from beacon_sim.filters.gaussian.unscented import (
    MAX_HEADING_OFFSET,
    cholesky3,
    correct,
    correct_low_rank,
    heading_limited_weights,
    innovation,
    innovation_parts,
    robust_sqrt,
    sigma_weights,
    unscented_gate,
)

#: Readings (rows of a tick's update) up to which the single-run UKF's update runs on Python
#: floats (:meth:`UnscentedKalmanFilter._update_floats`); above, the array forms (the direct
#: m x m solve, and over ``LOW_RANK_ROWS`` the low-rank one). numpy costs about a microsecond a
#: call on these tiny arrays, so for a handful of readings the floats are several times faster.
FLOAT_ROWS = 8

#: Readings up to which that update also solves on floats (above: S and the solve on arrays).
FLOAT_SOLVE_ROWS = 5

#: Rows per reading of each kind the UKF uses (a fix has one reading).
_ROWS_PER_READING = {"bearing": 1, "range_bearing": 2, "pose": 3, "position": 2}
_PI = math.pi
_TWO_PI = 2.0 * math.pi


def _s_entry(d: Sequence[float], f: Sequence[float], wc1: float, rc: float) -> float:
    """``sum_k Wc_k d_k f_k`` over the 7 sigma points (Wc_0 = rc Wc_1, Wc_k = Wc_1 for k > 0)."""
    d0, d1, d2, d3, d4, d5, d6 = d
    f0, f1, f2, f3, f4, f5, f6 = f
    return wc1 * (rc * d0 * f0 + d1 * f1 + d2 * f2 + d3 * f3 + d4 * f4 + d5 * f5 + d6 * f6)


def _gate_distance(rows: list[tuple[float, ...]], nu: list[float], r: list[float], wc1: float, rc: float,
                   i: int, j: int) -> float:
    """``nu_b^T S_bb^-1 nu_b`` of rows i..j-1 (one beacon or fix), S from the residuals ``rows``."""
    if j - i == 1:
        return nu[i] * nu[i] / (_s_entry(rows[i], rows[i], wc1, rc) + r[i])
    Sb = [[_s_entry(rows[a], rows[b], wc1, rc) + (r[a] if a == b else 0.0) for b in range(i, j)]
          for a in range(i, j)]
    if j - i == 2:
        (s00, s01), (_, s11) = Sb
        n0, n1 = nu[i], nu[i + 1]
        return (s11 * n0 * n0 - 2.0 * s01 * n0 * n1 + s00 * n1 * n1) / (s00 * s11 - s01 * s01)
    nb = np.array(nu[i:j])
    return float(nb @ np.linalg.solve(np.array(Sb), nb))


def _conditioned_floats(rows: list[tuple[float, ...]], r: list[float], B: list[list[float]], wc1: float,
                        rc: float) -> tuple[float, ...] | None:
    """``Pxz S^-1 Pxz^T`` (six entries) and ``Pxz S^-1 nu`` (three) on floats, with
    S = sum Wc dZ dZ^T + diag(r) from the residuals ``rows`` (7 each) and ``B`` the rows
    [Pxz^T row, nu] (changed in place). The readings are conditioned on one at a time (a
    symmetric elimination of [[S, B], [B^T, 0]]); None when a pivot is not positive."""
    S = []                                             # lower triangle, one list per row
    for j, (d0, d1, d2, d3, d4, d5, d6) in enumerate(rows):
        g0 = rc * d0
        row = [wc1 * (g0 * f0 + d1 * f1 + d2 * f2 + d3 * f3 + d4 * f4 + d5 * f5 + d6 * f6)
               for f0, f1, f2, f3, f4, f5, f6 in rows[:j + 1]]
        row[j] += r[j]
        S.append(row)
    q00 = q01 = q02 = q11 = q12 = q22 = g0 = g1 = g2 = 0.0
    n = len(B)
    for p in range(n):
        s = S[p][p]
        if not s > 0.0:
            return None
        h0, h1, h2, h3 = B[p]
        k0, k1, k2, k3 = h0 / s, h1 / s, h2 / s, h3 / s
        q00 += h0 * k0
        q01 += h0 * k1
        q02 += h0 * k2
        q11 += h1 * k1
        q12 += h1 * k2
        q22 += h2 * k2
        g0 += h0 * k3
        g1 += h1 * k3
        g2 += h2 * k3
        for q in range(p + 1, n):
            Sq = S[q]
            f = Sq[p] / s
            for col in range(p + 1, q + 1):
                Sq[col] -= f * S[col][p]
            Bq = B[q]
            Bq[0] -= f * h0
            Bq[1] -= f * h1
            Bq[2] -= f * h2
            Bq[3] -= f * h3
    return q00, q01, q02, q11, q12, q22, g0, g1, g2


def _conditioned_arrays(rows: list[tuple[float, ...]], r: list[float], B: list[list[float]], Wc: np.ndarray
                        ) -> tuple[float, ...] | None:
    """:func:`_conditioned_floats` with S and the solve on arrays (cheaper from a few rows on:
    S has m (m + 1) / 2 entries of 7 products each)."""
    A = np.array(rows)
    S = (A * Wc) @ A.T
    add_diagonal(S, np.array(r))
    Bm = np.array(B)
    Y = solve(S, Bm, strict=False)
    if not np.isfinite(Y).all():
        return None
    (q00, q01, q02, g0), (_, q11, q12, g1), (_, _, q22, g2), _ = (Bm.T @ Y).tolist()
    return q00, q01, q02, q11, q12, q22, g0, g1, g2



class UnscentedKalmanFilter(BatchableFilter):
    """UKF over ``[x, y, theta]`` for bearing, range-bearing, pose and position readings.

    The belief is kept on Python floats (``mean`` and ``cov`` are arrays made on request), and
    prediction and, for up to ``FLOAT_ROWS`` readings a tick, the update run on floats with
    the same equations as the array forms (:func:`innovation`, :func:`correct`); results agree
    with them to 1e-9 (tests/filters/test_ukf_fast.py).

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
                                "gate_chi2": 0.0, **association.GAUSSIAN_PARAMS}
    batch_params: ClassVar[dict[str, Any]] = {"alpha": None, "beta": None, "kappa": None,
                                              "scaled": None, "gate_chi2": None,
                                              **dict.fromkeys(association.GAUSSIAN_PARAMS)}
    sensor_kinds: ClassVar[tuple[str, ...]] = ("bearing", "range_bearing", "pose", "position")
    #: Readings of any other kind with a measurement model are weighed with that model.
    weighs_kind_models: ClassVar[bool] = True

    def __init__(self, ctx: FilterContext):
        super().__init__(ctx)
        p = self.params
        self.c, self.Wm, self.Wc = sigma_weights(p["alpha"], p["beta"], p["kappa"], p["scaled"])
        self.sqrt_c = math.sqrt(self.c)
        self._wm, self._wc = self.Wm.tolist(), self.Wc.tolist()
        self.models = ReadingModels(ctx)
        self.gate = effective_gate(self)   # on when the scenario declares outliers
        self.rejected = 0  # readings dropped by the gate so far
        association.attach(self)  # unknown correspondence: the association state
        self._Wm_now, self._Wc_now = self.Wm, self.Wc  # the weights of the last sigma points
        self._x = self._y = self._th = 0.0             # the mean [m, m, rad]
        self._p = (1.0, 0.0, 0.0, 1.0, 0.0, 1.0)       # P's distinct entries p00 p01 p02 p11 p12 p22
        self.reset(None)

    @property
    def mean(self) -> np.ndarray:
        """The mean (3,) [m, m, rad], a new array."""
        return np.array([self._x, self._y, self._th])

    @mean.setter
    def mean(self, m: np.ndarray) -> None:
        self._x, self._y, self._th = np.asarray(m, dtype=float).reshape(3).tolist()

    @property
    def cov(self) -> np.ndarray:
        """The covariance (3, 3), a new array."""
        p00, p01, p02, p11, p12, p22 = self._p
        return np.array([[p00, p01, p02], [p01, p11, p12], [p02, p12, p22]])

    @cov.setter
    def cov(self, P: np.ndarray) -> None:
        """From a symmetric P (its upper triangle is read)."""
        (a00, a01, a02), (_, a11, a12), (_, _, a22) = np.asarray(P, dtype=float).tolist()
        self._p = (a00, a01, a02, a11, a12, a22)

    def reset(self, initial: GaussianBelief | None) -> None:
        initial = initial or broad_gaussian(self.ctx.world)
        x, y, th = np.asarray(initial.mean, dtype=float).reshape(3).tolist()
        self._x, self._y, self._th = x, y, wrap(th)
        cov = np.array(initial.cov, dtype=float)
        self.cov = 0.5 * (cov + cov.T)

    def estimate(self) -> tuple[np.ndarray, np.ndarray]:
        return self.mean, self.cov

    def batched(self, runs: int) -> BatchedUKF:
        return BatchedUKF(self.mean, self.cov, runs, self.ctx.motion_noise, self.sqrt_c, self.Wm, self.Wc,
                          self.gate)

    def _columns(self) -> tuple[tuple[float, float, float], ...]:
        """The columns a_1..a_n of sqrt(c P) (the sigma points are m, m + a_i, m - a_i), and the
        weights for them (``_Wm_now``, ``_Wc_now``: :func:`heading_limited_weights`).

        The 3x3 Cholesky factor on floats (a numpy call costs ~1 us, design.md section 9);
        ``robust_sqrt`` takes over when a pivot is not positive."""
        a00, a01, a02, a11, a12, a22 = self._p
        sc, self._Wm_now, self._Wc_now = heading_limited_weights(self.c, self.Wm, self.Wc, a22)
        try:
            (l00, l10, l20, l11, l21, l22), _ = cholesky3(a00, a01, a02, a11, a12, a22, math.sqrt)
            return (sc * l00, sc * l10, sc * l20), (0.0, sc * l11, sc * l21), (0.0, 0.0, sc * l22)
        except (ValueError, ZeroDivisionError):
            L = robust_sqrt(self.cov) * sc
            return tuple((a, b, c) for a, b, c in L.T.tolist())

    def _offsets(self) -> list[tuple[float, float, float]]:
        """The 2n + 1 sigma-point offsets from the mean: 0, +- columns of sqrt(c P)."""
        cols = self._columns()
        return [(0.0, 0.0, 0.0), *cols, *((-a, -b, -c) for a, b, c in cols)]

    def _weights_now(self) -> tuple[list[float], list[float]]:
        """The weights of the last :meth:`_columns` as lists (Wm, Wc)."""
        if self._Wm_now is self.Wm:
            return self._wm, self._wc
        return self._Wm_now.tolist(), self._Wc_now.tolist()  # a spread limited for a wide heading

    def _sigma_points(self) -> np.ndarray:
        """Sigma points, shape (7, 3): the mean plus the offsets (heading not wrapped)."""
        return self.mean + np.array(self._offsets())

    def predict(self, control: Control, dt: float) -> None:
        """The unscented transform of the velocity model, in closed form.

        The model moves a sigma point by ``v dt (cos th, sin th)`` and turns it by ``w dt``:
        only the heading enters nonlinearly. With the points at m, m +- a_i (heading offsets
        h_i = a_i[2], |h_i| <= pi/2: ``heading_limited_weights``), C, S = cos, sin of the mean
        heading and k = Wm_0 + 2 Wm_1 sum cos h_i, the weighted sums of the loop over the points
        (:meth:`_predict_points`) are::

            mean = m + v dt k (C, S, 0) + (0, 0, w dt)
            P    = 2 Wc_1 sum p_i p_i^T + g [[C^2, C S, 0], [C S, S^2, 0], [0, 0, 0]] + Q
            p_i  = a_i + v dt sin h_i (-S, C, 0),
            g    = (v dt)^2 (2 Wc_1 sum (cos h_i - k)^2 + Wc_0 (1 - k)^2)

        (the points m +- a_i give residuals +-p_i + v dt (cos h_i - k) (C, S, 0)); the same
        results to rounding. The heading mean is the circular mean's m + w dt (k > 0), or the
        centre's when ``Wm_0 < 0`` (as the loop); k <= 0 runs the loop."""
        v, w = float(control.v), float(control.omega)
        cols = self._columns()
        Wm, Wc = self._weights_now()
        wm0, wm1, wc0, wc1 = Wm[0], Wm[1], Wc[0], Wc[1]   # W_1 = ... = W_2n by construction
        (a0, a1, ha), (b0, b1, hb), (c0, c1, hc) = cols
        cos, sin = math.cos, math.sin
        ca, cb, cc = cos(ha), cos(hb), cos(hc)
        k = wm0 + 2.0 * wm1 * (ca + cb + cc)
        if wm0 >= 0.0 and not k > 0.0:
            self._predict_points(v, w, dt, cols, Wm, Wc)
            return
        m0, m1, m2 = self._x, self._y, self._th
        C, S = cos(m2), sin(m2)
        vdt = v * dt
        sa, sb, sc = vdt * sin(ha), vdt * sin(hb), vdt * sin(hc)
        pa0, pa1 = a0 - S * sa, a1 + C * sa
        pb0, pb1 = b0 - S * sb, b1 + C * sb
        pc0, pc1 = c0 - S * sc, c1 + C * sc
        ua, ub, uc, u0 = ca - k, cb - k, cc - k, 1.0 - k
        g = vdt * vdt * (2.0 * wc1 * (ua * ua + ub * ub + uc * uc) + wc0 * u0 * u0)
        w2 = 2.0 * wc1
        q00, q01, q02, q11, q12, q22 = process_cov_terms(self.ctx.motion_noise, m2, C, S, v, w, dt)
        self._p = (q00 + w2 * (pa0 * pa0 + pb0 * pb0 + pc0 * pc0) + g * C * C,
                   q01 + w2 * (pa0 * pa1 + pb0 * pb1 + pc0 * pc1) + g * C * S,
                   q02 + w2 * (pa0 * ha + pb0 * hb + pc0 * hc),
                   q11 + w2 * (pa1 * pa1 + pb1 * pb1 + pc1 * pc1) + g * S * S,
                   q12 + w2 * (pa1 * ha + pb1 * hb + pc1 * hc),
                   q22 + w2 * (ha * ha + hb * hb + hc * hc))
        vk = vdt * k
        self._x, self._y, self._th = m0 + vk * C, m1 + vk * S, wrap(m2 + w * dt)

    def motion_cross_covariance(self, control: Control, dt: float) -> np.ndarray:
        """``D = Cov(x_k, x_{k+1}^-)`` (3, 3) [state units squared]: the cross-covariance between
        the belief now and the prediction :meth:`predict` would make with ``control`` over
        ``dt`` [s], from the same sigma points (the unscented RTS smoother's gain is
        ``D (P_{k+1}^-)^-1``; Sarkka 2008). Reads the belief, changes nothing.

        The points m +- a_i move to m^- +- p_i plus a term shared by each pair (the
        closed form of :meth:`predict`), so ``D = 2 Wc_1 sum a_i p_i^T``: the noise Q is
        added after the points are moved and does not enter."""
        vdt = float(control.v) * dt
        cols = self._columns()
        wc1 = self._weights_now()[1][1]
        S, C = math.sin(self._th), math.cos(self._th)
        D = np.zeros((3, 3))
        for a0, a1, h in cols:
            s = vdt * math.sin(h)
            D += np.outer((a0, a1, h), (a0 - S * s, a1 + C * s, h))
        return 2.0 * wc1 * D

    def _predict_points(self, v: float, w: float, dt: float, cols: Sequence[tuple[float, float, float]],
                        Wm: list[float], Wc: list[float]) -> None:
        """:meth:`predict` as the loop over the sigma points (what the closed form sums)."""
        m0, m1, m2 = self._x, self._y, self._th
        vdt, wdt = v * dt, w * dt
        offsets = [(0.0, 0.0, 0.0), *cols, *((-a, -b, -c) for a, b, c in cols)]
        cos, sin = math.cos, math.sin
        cw, sw = cos(wdt), sin(wdt)
        # The velocity model on every sigma point; weighted sums for the mean as we go.
        Y = []
        x = y = sn = cs = 0.0
        # 2n + 1 weights and points by construction; zip(strict=...) costs ~0.35 us a call
        for wi, (d0, d1, d2) in zip(Wm, offsets):  # noqa: B905
            th = m2 + d2
            c, s = cos(th), sin(th)
            a, b = m0 + d0 + vdt * c, m1 + d1 + vdt * s
            th += wdt
            Y.append((a, b, th))
            x += wi * a
            y += wi * b
            # sin and cos of th + wdt from those of th (angle addition)
            sn += wi * (s * cw + c * sw)
            cs += wi * (c * cw - s * sw)
        th = math.atan2(sn, cs)                 # circular weighted mean of the heading
        if Wm[0] < 0.0:  # limited spread: the offsets are symmetric, the mean is the centre's
            th = m2 + wdt
        # P = sum Wc d d^T + Q with the heading residual wrapped.
        q00, q01, q02, q11, q12, q22 = process_cov_terms(self.ctx.motion_noise, m2, math.cos(m2),
                                                         math.sin(m2), v, w, dt)
        for wi, (a, b, c) in zip(Wc, Y):  # noqa: B905
            da, db = a - x, b - y
            dc = wrap(c - th)
            wa, wb, wc = wi * da, wi * db, wi * dc
            q00 += wa * da
            q01 += wa * db
            q02 += wa * dc
            q11 += wb * db
            q12 += wb * dc
            q22 += wc * dc
        self._x, self._y, self._th = x, y, wrap(th)
        self._p = (q00, q01, q02, q11, q12, q22)

    def update(self, measurements: Sequence[Measurement]) -> None:
        if not measurements:
            return
        measurements = association.associate_gaussian(self, measurements)  # unknown IDs: associated first
        rows = 0
        others = False
        for m in measurements:
            width = _ROWS_PER_READING.get(m.kind)
            if width is not None and len(m):
                rows += width if m.kind in FIX_KINDS else width * len(m)
            elif width is None:
                others = True
        if rows and (rows > FLOAT_ROWS or not self._update_floats(measurements)):
            self._update_arrays(measurements)
        if others:
            self._update_models(measurements)

    def _update_models(self, measurements: Sequence[Measurement]) -> None:
        """The readings of other kinds (``model_readings``), one after another: sigma points
        from the current belief through the kind's model h, its full R, the same
        :func:`innovation_parts` and :func:`correct` as the array form."""
        for spec, m, model in model_readings(self.ctx, measurements):
            mean, cov = self.mean, self.cov
            D = np.array(self._offsets())
            Z = model.expected(spec, m, mean + D, self.ctx.world)
            ang = model.angle_rows(m)
            sel = np.flatnonzero(ang) if ang.any() else None
            z = np.asarray(m.z, dtype=float).reshape(-1)
            dZ, WdZ, Pxz, nu = innovation_parts(Z, D, z, sel, self._Wm_now, self._Wc_now)
            S = dZ.T @ WdZ + model.noise_at(spec, m, self.ctx.world)
            self.mean, self.cov = correct(mean, cov, S, Pxz, nu)

    # -- the update on floats (a few readings) ----------------------------------------------
    def _update_floats(self, measurements: Sequence[Measurement]) -> bool:
        """:meth:`_update_arrays` on Python floats; False (nothing changed) when a pivot of S
        is not positive (then the array form, with its LU solve, decides).

        The same sigma points, circular means and wrapped residuals (wrap's arithmetic
        written out per point); S = sum Wc dZ dZ^T + R and Pxz = sum Wc dX dZ^T (the offsets
        are 0 and +-a_i, so Pxz = Wc_1 sum a_i (dZ_i - dZ_{i+n})^T); then the readings are
        conditioned on one at a time (a symmetric elimination of [[S, Pxz^T, nu]]), which
        gives P - Pxz S^-1 Pxz^T and Pxz S^-1 nu without forming S^-1."""
        (a0, a1, a2), (b0, b1, b2), (c0, c1, c2) = self._columns()
        Wm, Wc = self._weights_now()
        wm0, wm1, wc0, wc1 = Wm[0], Wm[1], Wc[0], Wc[1]   # W_1 = ... = W_2n by construction
        limited = wm0 < 0.0
        rm = wm0 / wm1                                    # W_1 > 0: the circular mean's ratio
        rc = wc0 / wc1
        X0, Y0, T0 = self._x, self._y, self._th
        X1, X2, X3, X4, X5, X6 = X0 + a0, X0 + b0, X0 + c0, X0 - a0, X0 - b0, X0 - c0
        Y1, Y2, Y3, Y4, Y5, Y6 = Y0 + a1, Y0 + b1, Y0 + c1, Y0 - a1, Y0 - b1, Y0 - c1
        T1, T2, T3, T4, T5, T6 = T0 + a2, T0 + b2, T0 + c2, T0 - a2, T0 - b2, T0 - c2  # not wrapped
        pi, two_pi = _PI, _TWO_PI
        sin, cos, atan2, hypot = math.sin, math.cos, math.atan2, math.hypot
        rows: list[tuple[float, ...]] = []                # per row: the residuals of the 7 points
        nus: list[float] = []
        rs: list[float] = []
        groups: list[tuple[int, int]] = []                # rows of one beacon or fix (the gate)

        def angle_row(z0: float, z1: float, z2: float, z3: float, z4: float, z5: float, z6: float,
                      z: float, r: float) -> None:
            if limited:  # residuals about the centre point (see innovation_parts)
                zh = z0 + wm1 * (wrap(z1 - z0) + wrap(z2 - z0) + wrap(z3 - z0) + wrap(z4 - z0)
                                 + wrap(z5 - z0) + wrap(z6 - z0))
            elif rm == 0.0:  # circular weighted mean (weights W_1 / W_1: the same angle)
                zh = atan2(sin(z1) + sin(z2) + sin(z3) + sin(z4) + sin(z5) + sin(z6),
                           cos(z1) + cos(z2) + cos(z3) + cos(z4) + cos(z5) + cos(z6))
            else:
                zh = atan2(rm * sin(z0) + sin(z1) + sin(z2) + sin(z3) + sin(z4) + sin(z5) + sin(z6),
                           rm * cos(z0) + cos(z1) + cos(z2) + cos(z3) + cos(z4) + cos(z5) + cos(z6))
            o = pi - zh
            d = ((z0 + o) % two_pi - pi, (z1 + o) % two_pi - pi, (z2 + o) % two_pi - pi,
                 (z3 + o) % two_pi - pi, (z4 + o) % two_pi - pi, (z5 + o) % two_pi - pi,
                 (z6 + o) % two_pi - pi)
            if max(d) >= pi:
                d = tuple(a - two_pi if a >= pi else a for a in d)
            nu = (z + o) % two_pi - pi
            rows.append(d)
            nus.append(nu - two_pi if nu >= pi else nu)
            rs.append(r)

        def linear_row(z0: float, z1: float, z2: float, z3: float, z4: float, z5: float, z6: float,
                       z: float, r: float) -> None:
            zh = wm0 * z0 + wm1 * (z1 + z2 + z3 + z4 + z5 + z6)
            rows.append((z0 - zh, z1 - zh, z2 - zh, z3 - zh, z4 - zh, z5 - zh, z6 - zh))
            nus.append(z - zh)
            rs.append(r)

        models = self.models
        where = models.beacon_xy
        for m in measurements:
            kind = m.kind
            if kind == "bearing" or kind == "range_bearing":
                var = models.reading_var.get(m.sensor) or models.reading_variance(m.sensor)
                ranged = kind == "range_bearing"
                for zrow, bid in zip(m.z.tolist(), m.beacon_ids.tolist()):  # noqa: B905
                    try:
                        bx, by = where[bid]
                    except KeyError:
                        bx, by = models.beacon(bid)  # raises the one-line FilterError
                    e0, e1, e2, e3, e4, e5, e6 = bx - X0, bx - X1, bx - X2, bx - X3, bx - X4, bx - X5, bx - X6
                    f0, f1, f2, f3, f4, f5, f6 = by - Y0, by - Y1, by - Y2, by - Y3, by - Y4, by - Y5, by - Y6
                    start = len(nus)
                    if ranged:
                        linear_row(hypot(e0, f0), hypot(e1, f1), hypot(e2, f2), hypot(e3, f3),
                                   hypot(e4, f4), hypot(e5, f5), hypot(e6, f6), zrow[0], var[0])
                    angle_row(atan2(f0, e0) - T0, atan2(f1, e1) - T1, atan2(f2, e2) - T2,
                              atan2(f3, e3) - T3, atan2(f4, e4) - T4, atan2(f5, e5) - T5,
                              atan2(f6, e6) - T6, zrow[-1], var[-1])
                    groups.append((start, len(nus)))
            elif (kind == "pose" or kind == "position") and len(m):
                fvar = models.fix_var(m)
                z = m.z.reshape(-1).tolist()
                start = len(nus)
                linear_row(X0, X1, X2, X3, X4, X5, X6, z[0], fvar[0])
                linear_row(Y0, Y1, Y2, Y3, Y4, Y5, Y6, z[1], fvar[1])
                if kind == "pose":
                    angle_row(T0, T1, T2, T3, T4, T5, T6, z[2], fvar[2])
                groups.append((start, len(nus)))
        # [Pxz^T row, nu] per row
        B: list[list[float]] = []
        for (_, d1, d2, d3, d4, d5, d6), nu in zip(rows, nus):  # noqa: B905
            e1, e2, e3 = wc1 * (d1 - d4), wc1 * (d2 - d5), wc1 * (d3 - d6)
            B.append([a0 * e1 + b0 * e2 + c0 * e3, a1 * e1 + b1 * e2 + c1 * e3, a2 * e1 + b2 * e2 + c2 * e3,
                      nu])
        rejected = 0
        if self.gate > 0.0:
            keep: list[int] = []
            for i, j in groups:
                if _gate_distance(rows, nus, rs, wc1, rc, i, j) > self.gate:
                    rejected += 1
                else:
                    keep.extend(range(i, j))
            if rejected:
                if not keep:
                    self.rejected += rejected
                    return True
                rows, rs, B = [rows[i] for i in keep], [rs[i] for i in keep], [B[i] for i in keep]
        if len(B) > FLOAT_SOLVE_ROWS:
            out = _conditioned_arrays(rows, rs, B, self._Wc_now)
        else:
            out = _conditioned_floats(rows, rs, B, wc1, rc)
        if out is None:
            return False
        q00, q01, q02, q11, q12, q22, g0, g1, g2 = out
        p00, p01, p02, p11, p12, p22 = self._p
        self._p = (p00 - q00, p01 - q01, p02 - q02, p11 - q11, p12 - q12, p22 - q22)
        self._x, self._y, self._th = X0 + g0, Y0 + g1, wrap(T0 + g2)
        self.rejected += rejected
        return True

    # -- the update on arrays (many readings, or a degenerate S) ---------------------------
    def _update_arrays(self, measurements: Sequence[Measurement]) -> None:
        st = stack(self.models, measurements)
        if st is None:
            return
        mean, cov = self.mean, self.cov
        D = np.array(self._offsets())             # redrawn from the predicted belief (seed 000)
        Z = st.predict(mean + D, wrap=False)      # (7, m); residuals are wrapped in innovation
        if Z.shape[-1] > LOW_RANK_ROWS:            # many readings: linear in them, S never formed
            self._update_low_rank(st, Z, D, mean, cov)
            return
        S, Pxz, nu = innovation(Z, D, st.z, st.r, st.angle_sel, self._Wm_now, self._Wc_now)
        if self.gate > 0.0:
            keep = self._gate(st, lambda i, j: S[i:j, i:j], nu)
            if keep is not None:
                if not keep.any():
                    return
                S, Pxz, nu = S[np.ix_(keep, keep)], Pxz[:, keep], nu[keep]
        self.mean, self.cov = correct(mean, cov, S, Pxz, nu)

    def _update_low_rank(self, st: StackedReadings, Z: np.ndarray, D: np.ndarray, mean: np.ndarray,
                         cov: np.ndarray) -> None:
        """The update for over ``LOW_RANK_ROWS`` readings (:func:`correct_low_rank`): the same
        results to 1e-9, linear in the readings; the gate tests each beacon's block of S."""
        dZ, WdZ, Pxz, nu = innovation_parts(Z, D, st.z, st.angle_sel, self._Wm_now, self._Wc_now)
        r = st.r
        if self.gate > 0.0:
            def block(i: int, j: int) -> np.ndarray:
                S = dZ[:, i:j].T @ WdZ[:, i:j]
                add_diagonal(S, r[i:j])
                return S
            keep = self._gate(st, block, nu)
            if keep is not None:
                if not keep.any():
                    return
                dZ, Pxz, nu, r = dZ[:, keep], Pxz[:, keep], nu[keep], r[keep]
        self.mean, self.cov = correct_low_rank(mean, cov, dZ, self._Wc_now, r, Pxz, nu)

    def _gate(self, st: StackedReadings, S_block: Callable[[int, int], np.ndarray],
              nu: np.ndarray) -> np.ndarray | None:
        """Rows to keep (bool mask), or None when every reading passes the chi-square gate.

        A beacon's rows (1 for a bearing, 2 for range-bearing) or a fix's rows are tested
        together against their block of S, ``S_block(i, j)`` = S[i:j, i:j]."""
        keep = np.ones(nu.shape[0], dtype=bool)
        for kind, a, b, _ in st.blocks:
            width = 1 if kind == "bearing" else 2 if kind == "range_bearing" else b - a
            for i in range(a, b, width):
                j = i + width
                d2 = float(nu[i:j] @ np.linalg.solve(S_block(i, j), nu[i:j]))
                if d2 > self.gate:
                    keep[i:j] = False
                    self.rejected += 1
        return None if keep.all() else keep


__all__ = ["MAX_HEADING_OFFSET", "BatchedUKF", "UnscentedKalmanFilter", "cholesky3", "correct",
           "correct_low_rank", "heading_limited_weights", "innovation", "innovation_parts", "robust_sqrt",
           "sigma_weights", "unscented_gate"]
