"""Extended Kalman filter for beacon readings and fixes (seed 000 eq. 7-10, seed 001).

State ``[x, y, theta]`` [m, m, rad]; the velocity motion model; measurements of any kind
(bearing, range-bearing, pose fix, position fix), any number per tick.

Prediction (seed 000 eq. 7, 9)::

    x_pred = f(x, u)                 velocity model, heading wrapped
    P_pred = F P F^T + Q             F = df/dx at x, Q = B M B^T + diag(pose_std^2)

Update, all readings of a tick in one stacked update linearised once at x_pred
(seed 000 eq. 8, 10; seed 001's range-bearing H)::

    y = wrap(z - h(x_pred))          every angle residual wrapped to [-pi, pi)
    S = H P H^T + R,  K = P H^T S^-1
    x = x_pred + K y
    P = (I - K H) P (I - K H)^T + K R K^T          (Joseph form, parameter ``joseph``;
                                                    expanded per scalar row, see update)

The readings are independent (R diagonal), so up to :data:`STACKED_ROWS` rows the stacked
update is computed as a sequence of scalar updates that keep the one linearisation point:
row i uses the innovation ``y_i - H_i (x - x_pred)``. That is algebraically the same update
as the stacked matrices, without any matrix inverse, and lets the whole filter run on Python
floats: a numpy call costs about 1 us even on a 3x3 array (design.md section 9). Above it
(many beacons in view) the float loop costs about 1.7 us a reading, so the tick's rows are
linearised on arrays and the same update is taken in information form, linear in the rows
(``measurements.kalman_update_low_rank``: ``G = H^T R^-1 H``, a 3x3 solve);
the two agree to rounding (tests/filters/test_ekf_stacked.py).

Optional gating (seed 001's closing advice): a beacon's reading (1 row, 2 rows for
range-bearing, the whole fix for pose/position) is dropped when its squared Mahalanobis
distance ``y_b^T S_b^-1 y_b`` against the predicted belief exceeds ``gate_chi2``.

R runs at once (:class:`BatchedEKF`, for ``evaluation.montecarlo``): the same prediction
code on arrays (R,) instead of floats, and the stacked update in matrix form
(``measurements.kalman_update``) on the readings of all runs in fixed slots; no
gating. The KF's prediction is this one with F = I; dead reckoning's batched form is this one alone.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.motion import MotionNoise
from beacon_sim.core.types import Control, Measurement
from beacon_sim.filters import association
from beacon_sim.filters.base import FilterContext, GaussianBelief, broad_gaussian
from beacon_sim.filters.gaussian.measurements import (
    KINDS,
    BatchableFilter,
    BatchedGaussian,
    ReadingModels,
    StackedReadings,
    cov_entries,
    cov_matrix,
    effective_gate,
    gated_rows,
    kalman_update,
    kalman_update_full,
    kalman_update_low_rank,
    model_readings,
    nis,
    process_cov_terms,
)

#: One row of the stacked model: (H0, H1, H2, innovation, variance, h).
Row = tuple[float, float, float, float, float, float]

#: Scalar readings (rows) in a tick above which the per-run EKF updates on arrays
#: (:meth:`ExtendedKalmanFilter.update_stacked`) instead of row by row on floats; at or
#: below it every shipped scenario (at most 14 rows a tick) keeps its results bit for bit.
#: The two forms cost the same at about 40-48 rows on the development machine (gate on or off).
STACKED_ROWS = 40

#: A beacon's chi-square distance within this relative distance of the gate is decided
#: again by the row-by-row form's own test (``_passes_gate``), so that rounding in the
#: array form can never drop a different reading.
GATE_RECHECK = 1e-9

_BEACON_KINDS = ("bearing", "range_bearing")


def predict_moments(x: Any, y: Any, th: Any, p: Sequence[Any], v: Any, w: Any, dt: float, c: Any,
                    s: Any, q: Sequence[Any], jacobian: bool = True) -> tuple[Any, Any, Any, tuple]:
    """The velocity model's prediction of the mean and the six distinct entries ``p`` =
    (p00, p01, p02, p11, p12, p22) of P, on floats (one run) or arrays (R,) (R runs).

    c, s: cos and sin of the prior heading th [rad]; v [m/s], w [rad/s], dt [s]; q: the
    entries of Q at the prior mean (``process_cov_terms``). Returns (x, y, theta, p) with
    ``P = F P F^T + Q``, F = [[1, 0, a], [0, 1, b], [0, 0, 1]], a = -v dt s, b = v dt c
    (seed 000 eq. 7, 9); ``jacobian=False``: ``P + Q`` (the linear KF's A = I, seed 003).
    """
    vdt = v * dt
    p00, p01, p02, p11, p12, p22 = p
    q00, q01, q02, q11, q12, q22 = q
    if jacobian:
        a = -vdt * s
        b = vdt * c
        p = (p00 + 2.0 * a * p02 + a * a * p22 + q00,
             p01 + a * p12 + b * p02 + a * b * p22 + q01,
             p02 + a * p22 + q02,
             p11 + 2.0 * b * p12 + b * b * p22 + q11,
             p12 + b * p22 + q12,
             p22 + q22)
    else:
        p = (p00 + q00, p01 + q01, p02 + q02, p11 + q11, p12 + q12, p22 + q22)
    return x + vdt * c, y + vdt * s, wrap(th + w * dt), p


class VelocityGaussian(BatchableFilter):
    """A Gaussian over ``[x, y, theta]`` on Python floats, predicted with the velocity model
    (:func:`predict_moments`); the EKF and the KF add their updates.

    ``jacobian`` (class attribute): True propagates P with F (EKF, dead reckoning), False
    with A = I (the linear KF).
    """

    jacobian: ClassVar[bool] = True

    def __init__(self, ctx: FilterContext):
        super().__init__(ctx)
        self.x = self.y = self.th = 0.0
        self.p: tuple[float, ...] = (1.0, 0.0, 0.0, 1.0, 0.0, 1.0)  # P's distinct entries
        self.reset(None)

    def reset(self, initial: GaussianBelief | None) -> None:
        initial = initial or broad_gaussian(self.ctx.world)
        m = np.asarray(initial.mean, dtype=float)
        c = np.asarray(initial.cov, dtype=float)
        c = 0.5 * (c + c.T)
        self.x, self.y, self.th = float(m[0]), float(m[1]), wrap(float(m[2]))
        (p00, p01, p02), (_, p11, p12), (_, _, p22) = c.tolist()
        self.p = (p00, p01, p02, p11, p12, p22)

    @property
    def mean(self) -> np.ndarray:
        return np.array([self.x, self.y, self.th])

    @property
    def cov(self) -> np.ndarray:
        p00, p01, p02, p11, p12, p22 = self.p
        return np.array([[p00, p01, p02], [p01, p11, p12], [p02, p12, p22]])

    def estimate(self) -> tuple[np.ndarray, np.ndarray]:
        return self.mean, self.cov

    def predict(self, control: Control, dt: float) -> None:
        v, w = float(control.v), float(control.omega)
        th = self.th
        c, s = math.cos(th), math.sin(th)
        q = process_cov_terms(self.ctx.motion_noise, th, c, s, v, w, dt)
        self.x, self.y, self.th, self.p = predict_moments(self.x, self.y, th, self.p, v, w, dt, c, s, q,
                                                          self.jacobian)

    def update(self, measurements: Sequence[Measurement]) -> None:
        """No measurement update here."""


class BatchedVelocityGaussian(BatchedGaussian):
    """:class:`VelocityGaussian` for R runs: the same :func:`predict_moments` on arrays (R,)."""

    jacobian: ClassVar[bool] = True

    def predict(self, v: np.ndarray, w: np.ndarray, dt: float) -> None:
        m = self.mean
        th = m[:, 2]
        c, s = np.cos(th), np.sin(th)
        q = process_cov_terms(self.noise, th, c, s, v, w, dt)
        x, y, th, p = predict_moments(m[:, 0], m[:, 1], th, cov_entries(self.cov), v, w, dt, c, s, q,
                                      self.jacobian)
        mean = np.empty_like(m)
        mean[:, 0], mean[:, 1], mean[:, 2] = x, y, th
        self.mean = mean
        self.cov = cov_matrix(p)


class ExtendedKalmanFilter(VelocityGaussian):
    """EKF over ``[x, y, theta]`` for bearing, range-bearing, pose and position readings.

    Parameters (``ctx.params``)
    ---------------------------
    gate_chi2 : float, default 0.0
        0 turns gating off; otherwise the chi-square threshold a beacon's reading must stay
        below to be used (e.g. 6.63 = 99 % for 1 dof bearings, 9.21 for 2 dof range-bearing).
    joseph : bool, default True
        Joseph-form covariance update; False uses ``P - K S K^T``.
    """

    defaults: ClassVar[dict] = {"gate_chi2": 0.0, "joseph": True, **association.GAUSSIAN_PARAMS}
    batch_params: ClassVar[dict[str, Any]] = {"joseph": None, "gate_chi2": None,
                                              **dict.fromkeys(association.GAUSSIAN_PARAMS)}
    sensor_kinds: ClassVar[tuple[str, ...]] = ("bearing", "range_bearing", "pose", "position")
    #: Readings of any other kind with a measurement model are weighed with that model.
    weighs_kind_models: ClassVar[bool] = True

    def __init__(self, ctx: FilterContext):
        self.models = ReadingModels(ctx)
        super().__init__(ctx)
        self.gate = effective_gate(self)   # on when the scenario declares outliers
        self.joseph = bool(self.params["joseph"])
        self.rejected = 0  # readings dropped by the gate so far
        association.attach(self)  # unknown correspondence: the association state

    def batched(self, runs: int) -> BatchedEKF:
        mean, cov = self.estimate()
        return BatchedEKF(mean, cov, runs, self.ctx.motion_noise, self.joseph, self.gate)

    # -- update --------------------------------------------------------------------------
    def linearise(self, measurements: Sequence[Measurement]) -> list[Sequence[Row]]:
        """The stacked model at the current mean, grouped per beacon (or per fix).

        Returns a list of groups; each group is a sequence of rows
        ``(H0, H1, H2, innovation, variance, h)``: the Jacobian row dh/d[x, y, theta], the
        residual ``z - h(mean)`` (wrapped for angles), the noise variance and h itself.
        The same model as ``StackedReadings.linearise`` (the batched form's), on floats.
        """
        x, y, th = self.x, self.y, self.th
        groups: list[Sequence[Row]] = []
        models = self.models
        atan2, sqrt, wrap_ = math.atan2, math.sqrt, wrap  # locals: the per-reading hot path
        for m in measurements:
            kind = m.kind
            if kind == "bearing" or kind == "range_bearing":
                var = models.reading_var.get(m.sensor) or models.reading_variance(m.sensor)
                vb = var[-1]
                where = models.beacon_xy
                # one row per beacon ID by construction; zip(strict=...) costs ~0.35 us a call
                for zrow, bid in zip(m.z.tolist(), m.beacon_ids.tolist()):  # noqa: B905
                    try:
                        bx, by = where[bid]
                    except KeyError:
                        bx, by = models.beacon(bid)  # raises the one-line FilterError
                    dx = bx - x
                    dy = by - y
                    q = dx * dx + dy * dy
                    # bearing h = atan2(dy, dx) - theta, H = [dy/q, -dx/q, -1] (seed 000 eq. 10):
                    # measurement_models.relative_bearing_scalar inlined (a call per reading
                    # costs 5 %; tests/filters/test_ekf.py holds the update to the model's)
                    hb = wrap_(atan2(dy, dx) - th)
                    brow = (dy / q, -dx / q, -1.0, wrap_(zrow[-1] - hb), vb, hb)
                    if kind == "bearing":
                        groups.append((brow,))
                    else:
                        # range h = sqrt(q), H = [-dx/r, -dy/r, 0] (seed 001)
                        r = sqrt(q)
                        groups.append(((-dx / r, -dy / r, 0.0, zrow[0] - r, var[0], r), brow))
            elif kind == "pose" or kind == "position":
                fvar = models.fix_var(m)
                z = m.z.reshape(-1).tolist()
                rows = [(1.0, 0.0, 0.0, z[0] - x, fvar[0], x), (0.0, 1.0, 0.0, z[1] - y, fvar[1], y)]
                if kind == "pose":
                    rows.append((0.0, 0.0, 1.0, wrap(z[2] - th), fvar[2], th))
                groups.append(rows)
            # other kinds: nothing this filter can use
        return groups

    def _passes_gate(self, rows: Sequence[Row]) -> bool:
        """Squared Mahalanobis distance of one beacon's rows against the predicted belief
        within the gate. A bearing (1 row) or range-bearing (2 rows) is computed on floats
        in closed form; only a distance within :data:`GATE_RECHECK` of the gate is decided
        by the matrix form (:meth:`_passes_gate_matrix`), so the decisions are its own."""
        if len(rows) > 2:
            return self._passes_gate_matrix(rows)
        gate = self.gate
        p00, p01, p02, p11, p12, p22 = self.p
        a0, a1, a2, na, ra, _ = rows[0]
        u0 = p00 * a0 + p01 * a1 + p02 * a2
        u1 = p01 * a0 + p11 * a1 + p12 * a2
        u2 = p02 * a0 + p12 * a1 + p22 * a2
        saa = a0 * u0 + a1 * u1 + a2 * u2 + ra
        if len(rows) == 1:
            d = na * na / saa
        else:
            b0, b1, b2, nb, rb, _ = rows[1]
            sab = b0 * u0 + b1 * u1 + b2 * u2
            w0 = p00 * b0 + p01 * b1 + p02 * b2
            w1 = p01 * b0 + p11 * b1 + p12 * b2
            w2 = p02 * b0 + p12 * b1 + p22 * b2
            sbb = b0 * w0 + b1 * w1 + b2 * w2 + rb
            d = (sbb * na * na - 2.0 * sab * na * nb + saa * nb * nb) / (saa * sbb - sab * sab)
        if abs(d - gate) <= GATE_RECHECK * gate:
            return self._passes_gate_matrix(rows)
        return d <= gate  # NaN fails

    def _passes_gate_matrix(self, rows: Sequence[Row]) -> bool:
        """:meth:`_passes_gate` by a linear solve of the block's S (the reference form)."""
        H = np.array([r[:3] for r in rows])
        nu = np.array([r[3] for r in rows])
        S = H @ self.cov @ H.T + np.diag([r[4] for r in rows])
        return float(nu @ np.linalg.solve(S, nu)) <= self.gate

    def update(self, measurements: Sequence[Measurement]) -> None:
        if not measurements:
            return
        measurements = association.associate_gaussian(self, measurements)  # unknown IDs: associated first
        rows = 0
        others = False
        for m in measurements:
            rows += m.z.size
            if m.kind not in KINDS:
                others = True
        if not (rows > STACKED_ROWS and self.update_stacked(measurements)):
            self.update_rows(measurements)
        if others:
            self.update_models(measurements)

    def update_models(self, measurements: Sequence[Measurement]) -> None:
        """The readings of other kinds (``model_readings``), one after another, each
        linearised at the current mean with its kind's model (H, the innovation, a full R)."""
        for spec, m, model in model_readings(self.ctx, measurements):
            H, nu, R = model.linearise(spec, m, self.mean, self.ctx.world)
            mean, P = kalman_update_full(self.mean, self.cov, H, nu, R, self.joseph)
            self.x, self.y, self.th = mean.tolist()
            (p00, p01, p02), (_, p11, p12), (_, _, p22) = P.tolist()
            self.p = (p00, p01, p02, p11, p12, p22)

    def update_rows(self, measurements: Sequence[Measurement]) -> None:
        """The update row by row on floats (one linearisation point; see the module)."""
        groups = self.linearise(measurements)
        if not groups:
            return
        if self.gate > 0.0:
            kept = [g for g in groups if self._passes_gate(g)]
            self.rejected += len(groups) - len(kept)
            groups = kept
        p00, p01, p02, p11, p12, p22 = self.p
        d0 = d1 = d2 = 0.0  # x - x_pred accumulated over the rows
        joseph = self.joseph
        for g in groups:
            for h0, h1, h2, nu, r, _ in g:
                nu -= h0 * d0 + h1 * d1 + h2 * d2    # innovation at the one linearisation point
                u0 = p00 * h0 + p01 * h1 + p02 * h2  # u = P H_i^T
                u1 = p01 * h0 + p11 * h1 + p12 * h2
                u2 = p02 * h0 + p12 * h1 + p22 * h2
                s = h0 * u0 + h1 * u1 + h2 * u2 + r  # S_i = H_i P H_i^T + r_i
                k0 = u0 / s                          # K_i = P H_i^T / S_i
                k1 = u1 / s
                k2 = u2 / s
                d0 += k0 * nu
                d1 += k1 * nu
                d2 += k2 * nu
                if joseph:
                    # Joseph form (I - K H) P (I - K H)^T + r K K^T, expanded for a scalar
                    # row: P - K u^T - u K^T + s K K^T (exact for any gain K, so rounding
                    # in K does not break symmetry or positive semi-definiteness).
                    p00 += (s * k0 - 2.0 * u0) * k0
                    p01 += s * k0 * k1 - k0 * u1 - u0 * k1
                    p02 += s * k0 * k2 - k0 * u2 - u0 * k2
                    p11 += (s * k1 - 2.0 * u1) * k1
                    p12 += s * k1 * k2 - k1 * u2 - u1 * k2
                    p22 += (s * k2 - 2.0 * u2) * k2
                else:
                    # P = P - K S K^T = P - u u^T / s
                    p00 -= u0 * k0
                    p01 -= u0 * k1
                    p02 -= u0 * k2
                    p11 -= u1 * k1
                    p12 -= u1 * k2
                    p22 -= u2 * k2
        self.p = (p00, p01, p02, p11, p12, p22)
        self.x += d0
        self.y += d1
        self.th = wrap(self.th + d2)


    def update_stacked(self, measurements: Sequence[Measurement]) -> bool:
        """The tick's update as one stacked update on arrays: H, the innovations and the
        variances of every reading at the predicted mean, the gate per beacon (or fix) on
        arrays with the same decisions as :meth:`update_rows`, then the information form
        (``kalman_update_low_rank``), linear in the rows. The same update as
        :meth:`update_rows` to rounding. Returns False (nothing done) when a reading comes
        from a beacon at the robot's position, where the row form raises."""
        stacked = self._stack(measurements)
        if stacked is None:
            return False
        H, nu, r, rejected = stacked
        self.rejected += rejected
        if not nu.shape[0]:
            return True
        mean, P, _ = kalman_update_low_rank(self.mean, self.cov, H, nu, r, self.joseph)
        self.x, self.y, self.th = mean.tolist()
        (p00, p01, p02), (_, p11, p12), (_, _, p22) = P.tolist()
        self.p = (p00, p01, p02, p11, p12, p22)
        return True

    def _stack(self, measurements: Sequence[Measurement]
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int] | None:
        """The gated rows of the tick as arrays ``(H (m, 3), nu (m,), r (m,), rejected)``,
        the model of :meth:`linearise` (the same formulas, element by element); None when
        a beacon sits at the robot's position (q = 0)."""
        x, y, th = self.x, self.y, self.th
        models = self.models
        gate = self.gate
        P = self.cov if gate > 0.0 else None
        Hs: list[np.ndarray] = []
        nus: list[np.ndarray] = []
        rs: list[np.ndarray] = []
        rejected = 0
        for m in measurements:
            kind = m.kind
            if kind in _BEACON_KINDS:
                var = models.reading_variance(m.sensor)
                bxy = models.beacons(m.beacon_ids)
                z = m.z
                k = z.shape[0]
                dx = bxy[:, 0] - x
                dy = bxy[:, 1] - y
                q = dx * dx + dy * dy
                if not (q > 0.0).all():
                    return None
                Hb = np.empty((k, 3))
                Hb[:, 0] = dy / q
                Hb[:, 1] = -dx / q
                Hb[:, 2] = -1.0
                nub = wrap(z[:, -1] - wrap(np.arctan2(dy, dx) - th))
                vb = var[-1]
                if kind == "bearing":
                    H, nu, r = Hb, nub, np.full(k, vb)
                    if P is not None:
                        d = nub * nub / (_quad(Hb, P, Hb) + vb)
                else:
                    rr = np.sqrt(q)
                    Hr = np.zeros((k, 3))
                    Hr[:, 0] = -dx / rr
                    Hr[:, 1] = -dy / rr
                    nur = z[:, 0] - rr
                    H = np.concatenate([Hr, Hb])
                    nu = np.concatenate([nur, nub])
                    r = np.concatenate([np.full(k, var[0]), np.full(k, vb)])
                    if P is not None:
                        s00 = _quad(Hr, P, Hr) + var[0]
                        s01 = _quad(Hr, P, Hb)
                        s11 = _quad(Hb, P, Hb) + vb
                        d = (s11 * nur * nur - 2.0 * s01 * nur * nub + s00 * nub * nub) \
                            / (s00 * s11 - s01 * s01)
                if P is not None:
                    keep = d <= gate                      # NaN fails, as in _passes_gate
                    near = np.abs(d - gate) <= GATE_RECHECK * gate if math.isfinite(gate) else ()
                    for j in np.flatnonzero(near).tolist():
                        one = Measurement(m.sensor, kind, z[j:j + 1], m.beacon_ids[j:j + 1])
                        keep[j] = self._passes_gate_matrix(self.linearise([one])[0])
                    kept = int(np.count_nonzero(keep))
                    rejected += k - kept
                    if kept < k:
                        w = 1 if kind == "bearing" else 2
                        rows = np.tile(keep, w)
                        H, nu, r = H[rows], nu[rows], r[rows]
            elif kind == "pose" or kind == "position":
                g = self.linearise([m])[0]
                if gate > 0.0 and not self._passes_gate(g):
                    rejected += 1
                    continue
                H = np.array([row[:3] for row in g])
                nu = np.array([row[3] for row in g])
                r = np.array([row[4] for row in g])
            else:
                continue  # other kinds: nothing this filter can use
            Hs.append(H)
            nus.append(nu)
            rs.append(r)
        if not Hs:
            return np.zeros((0, 3)), np.zeros(0), np.zeros(0), rejected
        if len(Hs) == 1:
            return Hs[0], nus[0], rs[0], rejected
        return np.concatenate(Hs), np.concatenate(nus), np.concatenate(rs), rejected


def _quad(A: np.ndarray, P: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``a_i P b_i^T`` for the rows of A and B (k, 3): the entries of a block of H P H^T."""
    return np.einsum("ki,ij,kj->k", A, P, B)


class BatchedEKF(BatchedVelocityGaussian):
    """:class:`ExtendedKalmanFilter` for R runs: its prediction, its gate (``gate`` > 0:
    :func:`~beacon_sim.filters.gaussian.measurements.gated_rows`, the per-run filter's test
    on arrays), and its update in stacked matrix form. ``last_nis`` is the NIS of all the
    tick's readings against the predicted belief, gated or not (as the per-run NIS)."""

    own_nis = True

    def __init__(self, mean0: np.ndarray, cov0: np.ndarray, runs: int, noise: MotionNoise,
                 joseph: bool = True, gate: float = 0.0):
        super().__init__(mean0, cov0, runs, noise)
        self.joseph = joseph
        self.gate = float(gate)
        self.rejected = np.zeros(runs, dtype=np.int64)  # readings dropped by the gate, per run

    def update(self, st: StackedReadings) -> None:
        H, nu, r = st.linearise(self.mean)
        if self.gate > 0.0:
            prior_nis = nis(self.mean, self.cov, st)
            H, nu, dropped = gated_rows(st, self.cov, H, nu, r, self.gate)
            self.rejected += dropped
            self.mean, self.cov, _ = kalman_update(self.mean, self.cov, H, nu, r, self.joseph,
                                                   strict=False)
            self.last_nis = prior_nis
            return
        self.mean, self.cov, self.last_nis = kalman_update(self.mean, self.cov, H, nu, r, self.joseph,
                                                           want_nis=True, strict=False)


__all__ = [
    "GATE_RECHECK", "STACKED_ROWS", "BatchedEKF", "BatchedVelocityGaussian", "ExtendedKalmanFilter",
    "Row", "VelocityGaussian", "predict_moments"
]
