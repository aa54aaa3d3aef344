"""What a run leaves: a filter's record over a run (:class:`FilterRun`: errors, variances,
NEES, NIS, cost, failure), a run's records (:class:`RunOutput`, :class:`TeamRunOutput`),
and the judgement of its estimates (:func:`finish_filter`: an unusable estimate ends the
run's figures where it came).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from beacon_sim.core.metrics import nees as nees_of
from beacon_sim.core.metrics import pose_errors
from beacon_sim.hosting.guard import DIVERGED, MAX_COV, MAX_MEAN, NEES_NOT_FINITE


@dataclass
class FilterRun:
    """One filter in one run. Arrays have one row per step; rows after a failure are NaN.

    err : (T, 3) [m, m, rad] estimate - truth, heading wrapped.
    var : (T, 3) the diagonal of the filter's covariance.
    nees : (T,) ``e^T P^-1 e``.
    """

    err: np.ndarray
    var: np.ndarray
    nees: np.ndarray
    nis_sum: float
    nis_dof: int
    step_ns: int
    steps: int
    failed: str | None = None
    means: np.ndarray | None = None  # (T, 3), kept for the first run only (trajectory plot)
    #: A hosted SLAM filter's map after its last step: (ids (M,) or None, means (M, 2) [m],
    #: covs (M, 2, 2) [m^2]), judged as it came back (hosting/wire.py); None without a map.
    landmarks: tuple[np.ndarray | None, np.ndarray, np.ndarray] | None = None
    #: Its final ``joint()`` (mean (3 + 2M,), cov, landmark IDs (M,)), when it has one.
    joint: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None


@dataclass
class RunOutput:
    """One run: the truth, the commands, kidnaps, and each filter's record."""

    index: int
    seed: int
    truth: np.ndarray  # (T + 1, 3), row 0 = initial pose
    controls: np.ndarray  # (T, 2) [m/s, rad/s]
    kidnapped: np.ndarray  # (T,) bool
    truth_checksum: str
    filters: dict[str, FilterRun] = field(default_factory=dict)


def _check(means: np.ndarray, covs: np.ndarray) -> tuple[int, str | None]:
    """Index of the first unusable estimate and why, in the guard's words and by its rules
    (:func:`~beacon_sim.hosting.guard.validate_estimate`: non-finite, diverged, asymmetric
    or not PSD), so that ``eval`` and ``grade`` fail a filter where ``run`` does, and say
    the same (they once let a covariance grow to 1e100)."""
    n = means.shape[0]
    bad = ~(np.all(np.isfinite(means), axis=1) & np.all(np.isfinite(covs), axis=(1, 2)))
    first = int(np.argmax(bad)) if bad.any() else n
    if first < n:
        return first, "estimate() returned NaN or infinity"
    scale = np.maximum(np.max(np.abs(covs), axis=(1, 2)), 1e-12)
    huge = (scale > MAX_COV) | (np.max(np.abs(means), axis=1) > MAX_MEAN)
    asym = np.max(np.abs(covs - np.swapaxes(covs, 1, 2)), axis=(1, 2)) > 1e-6 * scale
    sym = 0.5 * (covs + np.swapaxes(covs, 1, 2))
    notpsd = np.zeros(n, dtype=bool)
    unsure = ~_cholesky_ok(sym) & ~huge  # Cholesky's pivots all positive: no eigenvalue below the bound
    if unsure.any():
        try:
            notpsd[unsure] = np.linalg.eigvalsh(sym[unsure])[:, 0] < -1e-9 * scale[unsure]
        except np.linalg.LinAlgError:  # no convergence: not a usable covariance either
            notpsd[unsure] = True
    for mask in (huge, asym, notpsd):
        if mask.any():
            first = min(first, int(np.argmax(mask)))
    if first < n:
        if huge[first]:
            return first, DIVERGED
        return first, ("covariance is not symmetric" if asym[first]
                       else "covariance is not positive semi-definite")
    return n, None


def _cholesky_ok(P: np.ndarray) -> np.ndarray:
    """(T,) bool: the 3x3 Cholesky factorisation of each P (T, 3, 3) runs with positive
    pivots in floating point. Then P is within a backward error of (n + 1) eps |P| (n = 3,
    about 1e-15 relative) of a positive definite matrix, so its smallest eigenvalue is above
    -1e-15 of its scale, far from the -1e-9 at which :func:`_check` calls it not positive
    semi-definite: eigvalsh would give the same verdict. False (NaN included): ask eigvalsh."""
    with np.errstate(all="ignore"):
        a00, a10, a20 = P[:, 0, 0], P[:, 1, 0], P[:, 2, 0]
        a11, a21, a22 = P[:, 1, 1], P[:, 2, 1], P[:, 2, 2]
        ok = a00 > 0.0
        l00 = np.sqrt(np.where(ok, a00, 1.0))
        l10 = a10 / l00
        l20 = a20 / l00
        p1 = a11 - l10 * l10
        ok &= p1 > 0.0
        l11 = np.sqrt(np.where(ok, p1, 1.0))
        l21 = (a21 - l20 * l10) / l11
        ok &= a22 - l20 * l20 - l21 * l21 > 0.0
    return ok


def finish_filter(m: np.ndarray, c: np.ndarray, truth: np.ndarray, done: int, failed: str | None,
                  nis_sum: float, nis_dof: int, step_ns: int, keep_means: bool) -> FilterRun:
    """One filter's record of one run from its estimates ``m`` (T, 3) and ``c`` (T, 3, 3)
    (modified: rows from the first unusable one on become NaN) and ``truth`` (T + 1, 3)."""
    T = m.shape[0]
    first, why = _check(m, c)
    if why and not failed:
        failed = why
    n_ok = min(first, done)
    m[n_ok:] = np.nan
    c[n_ok:] = np.nan
    err = pose_errors(m, truth[1:])
    nees = np.full(T, np.nan)
    if n_ok:
        with np.errstate(all="ignore"):
            nees[:n_ok] = nees_of(err[:n_ok], c[:n_ok])
        unbounded = ~np.isfinite(nees[:n_ok])
        if unbounded.any():  # a covariance that rules out its own error: the run fails there,
            n_ok = int(np.argmax(unbounded))  # before any other failure (which came later)
            failed = NEES_NOT_FINITE
            m[n_ok:], c[n_ok:], err[n_ok:], nees[n_ok:] = np.nan, np.nan, np.nan, np.nan
    var = np.einsum("tii->ti", c).copy()
    return FilterRun(err, var, nees, nis_sum, nis_dof, step_ns, done, failed,
                     m.copy() if keep_means else None)


def stack(runs: list[RunOutput], name: str, attr: str) -> np.ndarray:
    """One filter's per-step array from every run, stacked: (R, T, ...)."""
    return np.stack([getattr(r.filters[name], attr) for r in runs])


@dataclass
class TeamRunOutput:
    """One run over N robots: the truth (T + 1, N, 3) with row 0 the start, the commands
    (T, N, 2), kidnaps (T, N), and per filter one :class:`FilterRun` per robot (team order)."""

    index: int
    seed: int
    truth: np.ndarray
    controls: np.ndarray
    kidnapped: np.ndarray
    truth_checksum: str
    filters: dict[str, list[FilterRun]] = field(default_factory=dict)

    def robot(self, i: int) -> RunOutput:
        """Robot i's view as a single-robot run (what ``summary.evaluate`` reads)."""
        out = RunOutput(self.index, self.seed, self.truth[:, i], self.controls[:, i],
                        self.kidnapped[:, i], self.truth_checksum)
        out.filters = {name: runs[i] for name, runs in self.filters.items()}
        return out
