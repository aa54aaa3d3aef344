"""Monte Carlo runs with the Gaussian filters batched across runs.

Each run keeps its own :class:`Simulation` (so the truth is bit for bit that of
``Simulation(scenario, seed)``); the filters of all runs of a batch are one object per
filter whose state is arrays: mean (R, 3) [m, m, rad], covariance (R, 3, 3). One numpy
call then updates every run at once, instead of ~1 us of numpy overhead per 3x3 call
per run (design.md section 9).

The readings of one tick are packed into ``M`` slots per run, ``M`` fixed by the scenario
(every beacon of every beacon sensor, every fix row), so a run's numbers never depend on
which other runs share its batch (``--jobs 1`` and ``--jobs 2`` stay identical). Empty slots
have H = 0, innovation 0 and variance 1: they add an identity block to S and a zero column
to K, i.e. nothing.

The maths is that of ``filters/ekf.py``, ``ukf.py``, ``kf.py`` and ``dead_reckoning.py``:
the EKF's sequential scalar updates at one linearisation point are the stacked update
``S = H P H^T + R, K = P H^T S^-1`` written here in matrix form (same parameters:
``joseph``; ``gate_chi2`` > 0 is not batched), the UKF's sigma points, weights
(alpha, beta, kappa, scaled), circular means and wrapped residuals, the KF's pose and
position fixes (beacon readings ignored), dead reckoning's prediction only.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from beacon_sim.core.motion import MotionNoise
from beacon_sim.core.scenario import Scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.filters.dead_reckoning import DeadReckoning
from beacon_sim.filters.ekf import ExtendedKalmanFilter
from beacon_sim.filters.kf import KalmanFilter
from beacon_sim.filters.loading import (
    build_filter,
    filter_display_name,
    filter_names,
    load_filter_class,
    merged_params,
)
from beacon_sim.filters.ukf import UnscentedKalmanFilter, robust_sqrt, sigma_weights

try:  # the gufunc under np.linalg.solve: no Python wrapper, NaN instead of an exception
    from numpy.linalg import _umath_linalg as _ul

    _solve = _ul.solve
except (ImportError, AttributeError):  # pragma: no cover
    _solve = np.linalg.solve

PI = math.pi
TWO_PI = 2.0 * math.pi

# Slot kinds.
PAD, BEARING, RANGE, FIX_X, FIX_Y, FIX_TH = 0, 1, 2, 3, 4, 5
_BEACON_PATTERN = {"bearing": (BEARING,), "range_bearing": (RANGE, BEARING)}
_FIX_PATTERN = {"pose": (FIX_X, FIX_Y, FIX_TH), "position": (FIX_X, FIX_Y)}


def wrap(a: np.ndarray) -> np.ndarray:
    """Angles [rad] wrapped to [-pi, pi), elementwise (as ``filters.ekf._wrap``)."""
    a = (a + PI) % TWO_PI - PI
    return np.where(a >= PI, a - TWO_PI, a)


# -- one tick's readings of every run --------------------------------------------------
class Readings:
    """The readings of one tick for R runs in M slots per run.

    kind (R, M) slot kind; bx, by (R, M) [m] beacon of a beacon slot; z (R, M) the value
    [m or rad]; r (R, M) the variance the filters are told; dof (R,) used slots;
    has (R,) the run's step had any measurement (its NIS is recorded).
    """

    def __init__(self, kind, bx, by, z, r, dof, has):
        self.kind, self.bx, self.by, self.z, self.r, self.dof, self.has = kind, bx, by, z, r, dof, has
        self.valid = kind != PAD
        self.bearing = kind == BEARING
        self.range = kind == RANGE
        self.beacon = self.bearing | self.range
        self.fx = kind == FIX_X
        self.fy = kind == FIX_Y
        self.fth = kind == FIX_TH
        self.fix = self.fx | self.fy | self.fth
        self.angle = self.bearing | self.fth
        self.any_fix = bool(self.fix.any())


class ReadingPacker:
    """Packs the measurements of R runs' steps into :class:`Readings` (M fixed per scenario)."""

    def __init__(self, scenario: Scenario):
        world = scenario.world
        self.n_beacons = len(world.beacons)
        xy = np.asarray(world.beacon_xy, dtype=float).reshape(-1, 2)
        self.bx = np.append(xy[:, 0], 0.0)  # last entry: the empty slot
        self.by = np.append(xy[:, 1], 0.0)
        ids = np.asarray(world.beacon_ids, dtype=int)
        self.index = np.full(int(ids.max(initial=0)) + 1, -1)
        self.index[ids] = np.arange(len(ids))
        self.specs = {s.name: s for s in scenario.model_sensors}
        M = 0
        for s in scenario.sensors:
            if s.kind in _BEACON_PATTERN:
                M += self.n_beacons * len(_BEACON_PATTERN[s.kind])
            else:
                M += len(_FIX_PATTERN[s.kind])
        self.M = max(M, 1)
        self._cache: dict[tuple[str, int], tuple[np.ndarray, np.ndarray]] = {}

    def _beacon_rows(self, sensor: str, kind: str, k: int):
        key = (sensor, k)
        got = self._cache.get(key)
        if got is None:
            var = tuple(float(v) ** 2 for v in self.specs[sensor].reading_std())
            got = (np.array(_BEACON_PATTERN[kind] * k, dtype=np.int8), np.array(var * k))
            self._cache[key] = got
        return got

    def pack(self, steps) -> Readings | None:
        """None when no run has any measurement this tick."""
        R, M = len(steps), self.M
        pos, kinds, zs, rs, bidx = [], [], [], [], []
        has = np.zeros(R, dtype=bool)
        dof = np.zeros(R, dtype=int)
        for i, step in enumerate(steps):
            if not step.measurements:
                continue
            has[i] = True
            n0 = 0
            for m in step.measurements:
                kind = m.kind
                if kind in _BEACON_PATTERN:
                    k = len(m.beacon_ids)
                    if k == 0:
                        continue
                    kk, var = self._beacon_rows(m.sensor, kind, k)
                    b = self.index[m.beacon_ids]
                    if kind == "range_bearing":
                        b = np.repeat(b, 2)
                else:
                    std = self.specs[m.sensor].fix_std(len(m.beacon_ids), m.hdop)
                    kk = np.array(_FIX_PATTERN[kind], dtype=np.int8)
                    var = std * std
                    b = np.full(len(kk), self.n_beacons)
                n = len(kk)
                pos.append(np.arange(i * M + n0, i * M + n0 + n))
                kinds.append(kk)
                zs.append(m.z.reshape(-1))
                rs.append(var)
                bidx.append(b)
                n0 += n
            dof[i] = n0
        if not has.any():
            return None
        kind = np.zeros(R * M, dtype=np.int8)
        z = np.zeros(R * M)
        r = np.ones(R * M)
        b = np.full(R * M, self.n_beacons)
        if pos:
            p = np.concatenate(pos)
            kind[p] = np.concatenate(kinds)
            z[p] = np.concatenate(zs)
            r[p] = np.concatenate(rs)
            b[p] = np.concatenate(bidx)
        shape = (R, M)
        return Readings(kind.reshape(shape), self.bx[b].reshape(shape), self.by[b].reshape(shape),
                        z.reshape(shape), r.reshape(shape), dof, has)


def linearise(mean: np.ndarray, rd: Readings, use: np.ndarray):
    """The stacked model at ``mean`` (R, 3): H (R, M, 3), innovation ``z - h(mean)`` (R, M)
    (angles wrapped) and variances (R, M). Slots not in ``use`` get H = 0, 0 and 1.

    bearing h = atan2(dy, dx) - theta, H = [dy/q, -dx/q, -1]; range h = sqrt(q),
    H = [-dx/r, -dy/r, 0] (seed 000 eq. 10, seed 001); fixes h = x, y, theta, H = unit rows.
    """
    x = mean[:, 0:1]
    y = mean[:, 1:2]
    th = mean[:, 2:3]
    dx = rd.bx - x
    dy = rd.by - y
    q = np.where(rd.beacon, dx * dx + dy * dy, 1.0)
    rr = np.sqrt(q)
    hb = wrap(np.arctan2(dy, dx) - th)
    H = np.zeros((*rd.kind.shape, 3))
    H[..., 0] = np.where(rd.bearing, dy / q, np.where(rd.range, -dx / rr, rd.fx))
    H[..., 1] = np.where(rd.bearing, -dx / q, np.where(rd.range, -dy / rr, rd.fy))
    H[..., 2] = np.where(rd.bearing, -1.0, rd.fth)
    h = np.where(rd.bearing, hb, np.where(rd.range, rr, np.where(rd.fx, x, np.where(rd.fy, y, th))))
    nu = rd.z - h
    nu = np.where(rd.angle, wrap(nu), nu)
    if use is not rd.valid:
        H *= use[..., None]
    nu = np.where(use, nu, 0.0)
    r = np.where(use, rd.r, 1.0)
    return H, nu, r


def _add_diag(S: np.ndarray, r: np.ndarray) -> None:
    M = S.shape[-1]
    S.reshape(S.shape[0], -1)[:, :: M + 1] += r


def stacked_update(mean, P, H, nu, r, joseph: bool, want_nis: bool = False):
    """Kalman update of R runs with their stacked rows: returns (mean, P, nis or None).

    S = H P H^T + R, K = P H^T S^-1, x = x + K nu,
    P = (I - K H) P (I - K H)^T + K R K^T (Joseph) or P - K S K^T = P - K H P.
    """
    HP = H @ P                                          # (R, M, 3)
    S = HP @ np.swapaxes(H, 1, 2)                       # H P H^T
    _add_diag(S, r)                                     # + R
    rhs = np.concatenate([HP, nu[..., None]], axis=2) if want_nis else HP
    X = _solve(S, rhs)
    Kt = X[..., :3]                                     # K^T = S^-1 H P (P symmetric)
    nis = np.sum(nu * X[..., 3], axis=1) if want_nis else None
    K = np.swapaxes(Kt, 1, 2)                           # (R, 3, M)
    mean = mean + (nu[:, None, :] @ Kt)[:, 0, :]
    mean[:, 2] = wrap(mean[:, 2])
    if joseph:
        A = np.eye(3) - K @ H
        P = A @ P @ np.swapaxes(A, 1, 2) + (K * r[:, None, :]) @ Kt
    else:
        P = P - K @ HP
    P = 0.5 * (P + np.swapaxes(P, 1, 2))
    return mean, P, nis


def nis_of(mean, P, rd: Readings) -> np.ndarray:
    """Joint NIS (R,) of every reading of the tick against the prior ``(mean, P)``, as
    :func:`beacon_sim.evaluation.metrics.nis` (all kinds, the told noise)."""
    H, nu, r = linearise(mean, rd, rd.valid)
    S = H @ P @ np.swapaxes(H, 1, 2)
    _add_diag(S, r)
    return np.sum(nu * _solve(S, nu[..., None])[..., 0], axis=1)


# -- prediction shared by the EKF, the KF and dead reckoning --------------------------
class _MotionTerms:
    """The velocity model's terms for all runs: cos/sin of the prior heading and Q."""

    def __init__(self, noise: MotionNoise):
        self.noise = noise
        ps = noise.pose_std
        self.ps2 = (ps[0] * ps[0], ps[1] * ps[1], ps[2] * ps[2])

    def q(self, c, s, v, w, dt):
        """Q = B M B^T + diag(pose_std^2) (filters.gaussian_measurements.process_cov_terms)."""
        n = self.noise
        sv = n.v_std + n.v_frac * np.abs(v)
        sw = n.omega_std + n.omega_frac * np.abs(w)
        qv = dt * dt * sv * sv
        Q = np.zeros((len(v), 3, 3))
        Q[:, 0, 0] = qv * c * c + self.ps2[0]
        Q[:, 0, 1] = Q[:, 1, 0] = qv * c * s
        Q[:, 1, 1] = qv * s * s + self.ps2[1]
        Q[:, 2, 2] = dt * dt * sw * sw + self.ps2[2]
        return Q


class BatchedGaussian:
    """State of one Gaussian filter for R runs: ``mean`` (R, 3), ``cov`` (R, 3, 3)."""

    uses_fix_only = False

    def __init__(self, mean0: np.ndarray, cov0: np.ndarray, R: int, noise: MotionNoise):
        self.mean = np.tile(np.asarray(mean0, dtype=float), (R, 1))
        self.cov = np.tile(np.asarray(cov0, dtype=float), (R, 1, 1))
        self.terms = _MotionTerms(noise)
        self.last_nis: np.ndarray | None = None  # set by filters that get the NIS for free

    def _move(self, v, w, dt, c, s):
        """x += v dt cos, y += v dt sin, theta = wrap(theta + omega dt), in place."""
        m = self.mean
        m[:, 0] += v * dt * c
        m[:, 1] += v * dt * s
        m[:, 2] = wrap(m[:, 2] + w * dt)

    def predict(self, v, w, dt) -> None:
        """EKF / dead reckoning: P = F P F^T + Q, F = [[1, 0, -v dt s], [0, 1, v dt c], [0, 0, 1]]."""
        th = self.mean[:, 2]
        c, s = np.cos(th), np.sin(th)
        F = np.zeros_like(self.cov)
        F[:, 0, 0] = F[:, 1, 1] = F[:, 2, 2] = 1.0
        F[:, 0, 2] = -v * dt * s
        F[:, 1, 2] = v * dt * c
        self.cov = F @ self.cov @ np.swapaxes(F, 1, 2) + self.terms.q(c, s, v, w, dt)
        self._move(v, w, dt, c, s)

    def update(self, rd: Readings) -> None:
        """Measurement update; dead reckoning uses none."""


class BatchedDeadReckoning(BatchedGaussian):
    """``filters.dead_reckoning.DeadReckoning`` for R runs."""


class BatchedEKF(BatchedGaussian):
    """``filters.ekf.ExtendedKalmanFilter`` for R runs (``gate_chi2 = 0``)."""

    def __init__(self, mean0, cov0, R, noise, joseph: bool = True):
        super().__init__(mean0, cov0, R, noise)
        self.joseph = joseph

    def update(self, rd: Readings) -> None:
        H, nu, r = linearise(self.mean, rd, rd.valid)
        self.mean, self.cov, self.last_nis = stacked_update(self.mean, self.cov, H, nu, r,
                                                            self.joseph, want_nis=True)


class BatchedKF(BatchedGaussian):
    """``filters.kf.KalmanFilter`` for R runs: A = I, P = P + Q; pose / position fixes only."""

    def predict(self, v, w, dt) -> None:
        th = self.mean[:, 2]
        c, s = np.cos(th), np.sin(th)
        self.cov = self.cov + self.terms.q(c, s, v, w, dt)
        self._move(v, w, dt, c, s)

    def update(self, rd: Readings) -> None:
        if not rd.any_fix:
            return
        H, nu, r = linearise(self.mean, rd, rd.fix)
        self.mean, self.cov, _ = stacked_update(self.mean, self.cov, H, nu, r, joseph=True)


class BatchedUKF(BatchedGaussian):
    """``filters.ukf.UnscentedKalmanFilter`` for R runs."""

    def __init__(self, mean0, cov0, R, noise, alpha=1.0, beta=2.0, kappa=0.0, scaled=True):
        super().__init__(mean0, cov0, R, noise)
        c, self.Wm, self.Wc = sigma_weights(alpha, beta, kappa, scaled)
        self.sqrt_c = math.sqrt(c)

    def offsets(self) -> np.ndarray:
        """Sigma-point offsets (R, 7, 3): 0, +- the columns of sqrt(c P) (Cholesky; the
        scalar filter's ``robust_sqrt`` for the runs where a pivot is not positive)."""
        P = self.cov
        a00, a01, a02 = P[:, 0, 0], P[:, 0, 1], P[:, 0, 2]
        a11, a12, a22 = P[:, 1, 1], P[:, 1, 2], P[:, 2, 2]
        L = np.zeros_like(P)
        l00 = np.sqrt(a00)
        l10 = a01 / l00
        l20 = a02 / l00
        p1 = a11 - l10 * l10
        l11 = np.sqrt(p1)
        l21 = (a12 - l20 * l10) / l11
        p2 = a22 - l20 * l20 - l21 * l21
        L[:, 0, 0], L[:, 1, 0], L[:, 2, 0] = l00, l10, l20
        L[:, 1, 1], L[:, 2, 1] = l11, l21
        L[:, 2, 2] = np.sqrt(p2)
        bad = (a00 <= 0.0) | (p1 <= 0.0) | (p2 < 0.0)
        for i in np.flatnonzero(bad):
            L[i] = robust_sqrt(P[i])
        cols = self.sqrt_c * np.swapaxes(L, 1, 2)      # row j = column j of sqrt(c P)
        return np.concatenate([np.zeros((len(P), 1, 3)), cols, -cols], axis=1)

    def predict(self, v, w, dt) -> None:
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
        Wm, Wc = self.Wm, self.Wc
        x = np.sum(a * Wm, axis=1)
        y = np.sum(b * Wm, axis=1)
        sn = np.sum((s * cw + c * sw) * Wm, axis=1)
        cs = np.sum((c * cw - s * sw) * Wm, axis=1)
        thm = np.arctan2(sn, cs)                        # circular weighted mean
        dX = np.stack([a - x[:, None], b - y[:, None], wrap(th + wdt - thm[:, None])], axis=2)
        th0 = m[:, 2]
        Q = self.terms.q(np.cos(th0), np.sin(th0), v, w, dt)
        self.cov = np.swapaxes(dX * Wc[:, None], 1, 2) @ dX + Q
        self.mean = np.stack([x, y, wrap(thm)], axis=1)

    def update(self, rd: Readings) -> None:
        D = self.offsets()
        X = self.mean[:, None, :] + D                   # (R, 7, 3)
        xs = X[..., 0:1]
        ys = X[..., 1:2]
        ths = X[..., 2:3]
        bx = rd.bx[:, None, :]
        by = rd.by[:, None, :]
        dx = bx - xs
        dy = by - ys                                    # (R, 7, M)
        bearing = rd.bearing[:, None, :]
        Z = np.where(bearing, np.arctan2(dy, dx) - ths,
                     np.where(rd.range[:, None, :], np.hypot(dx, dy),
                              np.where(rd.fx[:, None, :], xs,
                                       np.where(rd.fy[:, None, :], ys,
                                                np.where(rd.fth[:, None, :], ths, 0.0)))))
        Wm, Wc = self.Wm, self.Wc
        zhat = np.einsum("i,rim->rm", Wm, Z)
        ang = rd.angle
        zc = np.arctan2(np.einsum("i,rim->rm", Wm, np.sin(Z)), np.einsum("i,rim->rm", Wm, np.cos(Z)))
        zhat = np.where(ang, zc, zhat)                  # circular means of the angle rows
        dZ = Z - zhat[:, None, :]
        nu = rd.z - zhat
        dZ = np.where(ang[:, None, :], wrap(dZ), dZ)
        nu = np.where(ang, wrap(nu), nu)
        nu = np.where(rd.valid, nu, 0.0)
        WdZ = dZ * Wc[:, None]
        S = np.swapaxes(dZ, 1, 2) @ WdZ                 # sum Wc dZ dZ^T
        _add_diag(S, rd.r)                              # + R (1 on empty slots)
        Pxz = np.swapaxes(D, 1, 2) @ WdZ                # sum Wc dX dZ^T, (R, 3, M)
        Kt = _solve(S, np.swapaxes(Pxz, 1, 2))          # K^T = S^-1 Pxz^T
        m = self.mean + (nu[:, None, :] @ Kt)[:, 0, :]
        m[:, 2] = wrap(m[:, 2])
        P = self.cov - Pxz @ Kt                         # P - K S K^T
        self.cov = 0.5 * (P + np.swapaxes(P, 1, 2))
        self.mean = m


BATCHED = {ExtendedKalmanFilter: "ekf", UnscentedKalmanFilter: "ukf", KalmanFilter: "kf",
           DeadReckoning: "dead_reckoning"}


def _make(cls, proto, R: int, noise: MotionNoise) -> BatchedGaussian:
    mean0, cov0 = proto.estimate()
    p = getattr(proto, "params", {})
    if cls is ExtendedKalmanFilter:
        return BatchedEKF(mean0, cov0, R, noise, joseph=bool(p["joseph"]))
    if cls is UnscentedKalmanFilter:
        return BatchedUKF(mean0, cov0, R, noise, p["alpha"], p["beta"], p["kappa"], p["scaled"])
    if cls is KalmanFilter:
        return BatchedKF(mean0, cov0, R, noise)
    return BatchedDeadReckoning(mean0, cov0, R, noise)


#: The parameters each batched form reproduces: None = any value, else the only value it does.
BATCHED_PARAMS: dict[type, dict[str, Any]] = {
    ExtendedKalmanFilter: {"joseph": None, "gate_chi2": 0.0},
    UnscentedKalmanFilter: {"alpha": None, "beta": None, "kappa": None, "scaled": None, "gate_chi2": 0.0},
    KalmanFilter: {},
    DeadReckoning: {},
}


def unsupported(scenario: Scenario, specs: list[str], params: dict[str, dict[str, Any]]) -> str | None:
    """Why these filters cannot run batched (None: they can). A filter class that gained a
    parameter the batched form does not know is never batched (no silent difference)."""
    if type(scenario.model_motion_noise) is not MotionNoise:
        return "the scenario's motion noise is not a plain MotionNoise"
    for s in scenario.sensors:
        if s.kind not in _BEACON_PATTERN and s.kind not in _FIX_PATTERN:
            return f"sensor kind {s.kind!r}"
    for spec in specs:
        try:
            cls = load_filter_class(spec)
        except Exception as exc:
            return str(exc)
        if cls not in BATCHED:
            return f"{spec} has no batched form"
        known = BATCHED_PARAMS[cls]
        extra = sorted(set(getattr(cls, "defaults", {})) - set(known))
        if extra:
            return f"{spec} parameter {extra[0]} is not batched"
        merged = merged_params(spec, scenario, params.get(filter_display_name(spec)))
        try:
            merged = cls.merge_params(merged)
        except Exception as exc:  # reported by the per-run path
            return str(exc)
        for key, only in known.items():
            if only is not None and key in merged and merged[key] != only:
                return f"{spec} {key} = {merged[key]!r} is not batched"
    return None


def batch_runs(scenario: Scenario, specs: list[str], params: dict[str, dict[str, Any]],
               seeds: list[int], duration: float, indices: list[int], keep_means_index: int = 0):
    """Runs ``seeds`` together; returns one :class:`RunOutput` per seed, as
    :func:`beacon_sim.evaluation.montecarlo.one_run` would (costs: the batch's cost per run-step)."""
    from beacon_sim.evaluation.montecarlo import RunOutput, finish_filter

    names = filter_names(specs)
    R = len(seeds)
    noise = scenario.model_motion_noise
    batched = {}
    for name, spec in zip(names, specs, strict=True):
        proto = build_filter(spec, scenario, seeds[0], name=name,
                             params=params.get(filter_display_name(spec)))
        batched[name] = _make(type(proto), proto, R, noise)
    sims = [Simulation(scenario, s) for s in seeds]
    packer = ReadingPacker(scenario)
    T = round(duration / scenario.dt)
    truth = np.empty((R, T + 1, 3))
    truth[:, 0] = [sim.pose for sim in sims]
    controls = np.empty((R, T, 2))
    kidnapped = np.zeros((R, T), dtype=bool)
    means = {n: np.empty((R, T, 3)) for n in names}
    covs = {n: np.empty((R, T, 3, 3)) for n in names}
    nis_sum = {n: np.zeros(R) for n in names}
    nis_dof = {n: np.zeros(R, dtype=int) for n in names}
    nis_alive = {n: np.ones(R, dtype=bool) for n in names}
    ns = dict.fromkeys(names, 0)
    clock = time.perf_counter_ns
    with np.errstate(all="ignore"):
        for t in range(T):
            steps = [sim.step() for sim in sims]
            uv = np.array([(s.control.v, s.control.omega) for s in steps])
            controls[:, t] = uv
            truth[:, t + 1] = [s.true_pose for s in steps]
            kidnapped[:, t] = [s.kidnapped for s in steps]
            v = uv[:, 0]
            w = uv[:, 1]
            dt = steps[0].dt
            rd = packer.pack(steps)
            for name, f in batched.items():
                t0 = clock()
                f.predict(v, w, dt)
                t1 = clock()
                prior = None
                if rd is not None and not isinstance(f, BatchedEKF):  # not timed (as one_run)
                    prior = nis_of(f.mean, f.cov, rd)
                t2 = clock()
                if rd is not None:
                    f.update(rd)
                    if prior is None:
                        prior = f.last_nis
                means[name][:, t] = f.mean
                covs[name][:, t] = f.cov
                t3 = clock()
                ns[name] += (t1 - t0) + (t3 - t2)
                if rd is not None:
                    alive = nis_alive[name]
                    alive &= np.isfinite(prior) | ~rd.has
                    use = alive & rd.has
                    nis_sum[name][use] += prior[use]
                    nis_dof[name][use] += rd.dof[use]
    out = []
    for i in range(R):
        run = RunOutput(indices[i], seeds[i], truth[i], controls[i], kidnapped[i], sims[i].truth_checksum)
        for name in names:
            run.filters[name] = finish_filter(
                means[name][i].copy(), covs[name][i].copy(), truth[i], T, None,
                float(nis_sum[name][i]), int(nis_dof[name][i]), round(ns[name] / R),
                keep_means=indices[i] == keep_means_index)
        out.append(run)
    return out


__all__ = ["BatchedDeadReckoning", "BatchedEKF", "BatchedKF", "BatchedUKF", "ReadingPacker",
           "Readings", "batch_runs", "linearise", "nis_of", "stacked_update", "unsupported"]
