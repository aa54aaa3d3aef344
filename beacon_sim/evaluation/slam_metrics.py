"""What a SLAM run is measured by (docs/slam.md, "Metrics").

- :func:`ate`: the absolute trajectory error, the RMS of the position error over the run
  [m]. No alignment: the filters start from the scenario's initial belief, so the map and
  the path are in the world frame already (anchors or the known start fix the gauge).
- :func:`gospa`: the generalised optimal sub-pattern assignment metric (Rahmathullah,
  Garcia-Fernandez and Svensson 2017; alpha = 2) between the estimated landmarks and the
  true beacons: paired landmarks cost their distance (cut off at ``c``), every missed beacon
  and every extra (duplicated or made-up) landmark ``c / 2^(1/p)``. Needs no IDs, so it
  scores maps made without correspondence too.
- :func:`joint_nees`: ``e^T P^-1 e`` over the pose and every landmark of a joint Gaussian
  (EKF-SLAM), the consistency test of the whole state; :func:`joint_anees_band`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.metrics import chi2_quantile
from beacon_sim.core.optional import optional


def ate(est_xy: np.ndarray, true_xy: np.ndarray) -> float:
    """RMS position error [m] of a path: estimates and truths of shape (T, 2) (or (T, 3))."""
    e = np.asarray(est_xy, dtype=float)[:, :2] - np.asarray(true_xy, dtype=float)[:, :2]
    return float(np.sqrt(np.mean(np.sum(e * e, axis=1)))) if e.size else math.nan


def min_cost_assignment(cost: np.ndarray) -> list[tuple[int, int]]:
    """The pairs (row, col), sorted, of a minimum-cost assignment of a rectangular cost
    matrix (n, m) of finite numbers: min(n, m) pairs.

    scipy's ``optimize.linear_sum_assignment`` when scipy is installed (the ``science``
    extra; 15-90x faster on 50-500 landmarks: benchmarks/bench_scipy_paths.py), else
    :func:`min_cost_assignment_numpy`. Both are exact: the same minimum cost, and the same
    pairs whenever the minimum is reached by one assignment only (tests/core/test_scipy_paths.py).
    """
    cost = np.asarray(cost, dtype=float)
    optimize = optional("scipy.optimize") if cost.size and np.isfinite(cost).all() else None
    if optimize is None:
        return min_cost_assignment_numpy(cost)
    rows, cols = optimize.linear_sum_assignment(cost)
    return sorted(zip(rows.tolist(), cols.tolist(), strict=True))


def min_cost_assignment_numpy(cost: np.ndarray) -> list[tuple[int, int]]:
    """:func:`min_cost_assignment` in numpy alone: the Hungarian method with shortest
    augmenting paths, O(n^2 m)."""
    cost = np.asarray(cost, dtype=float)
    transposed = cost.shape[0] > cost.shape[1]
    a = cost.T if transposed else cost
    n, m = a.shape
    if n == 0:
        return []
    INF = math.inf
    u = np.zeros(n + 1)
    v = np.zeros(m + 1)
    p = np.zeros(m + 1, dtype=int)     # p[j]: the row (1-based) given column j; 0 = none
    way = np.zeros(m + 1, dtype=int)
    for i in range(1, n + 1):
        p[0] = i
        j0 = 0
        minv = np.full(m + 1, INF)
        used = np.zeros(m + 1, dtype=bool)
        while True:
            used[j0] = True
            i0 = p[j0]
            cur = a[i0 - 1] - u[i0] - v[1:]
            free = ~used[1:]
            better = free & (cur < minv[1:])
            minv[1:][better] = cur[better]
            way[1:][better] = j0
            cand = np.where(free, minv[1:], INF)
            j1 = int(np.argmin(cand)) + 1
            delta = cand[j1 - 1]
            u[p[used]] += delta
            v[used] -= delta
            minv[1:][free] -= delta
            j0 = j1
            if p[j0] == 0:
                break
        while j0:
            j1 = way[j0]
            p[j0] = p[j1]
            j0 = j1
    pairs = [(int(p[j]) - 1, j - 1) for j in range(1, m + 1) if p[j] != 0]
    return sorted((c, r) for r, c in pairs) if transposed else sorted(pairs)


@dataclass(frozen=True)
class Gospa:
    """GOSPA between an estimated map and the true one.

    Attributes
    ----------
    value : float
        The metric [m].
    localisation : float
        Sum of squared distances of the pairs within ``c`` [m^2] (p = 2).
    missed, false : int
        True beacons with no landmark within ``c``; landmarks with no beacon within ``c``.
    pairs : tuple of (int, int)
        (landmark row, beacon row) pairs within ``c``.
    """

    value: float
    localisation: float
    missed: int
    false: int
    pairs: tuple[tuple[int, int], ...]


def gospa(est: np.ndarray, truth: np.ndarray, c: float = 1.0, p: float = 2.0) -> Gospa:
    """GOSPA (alpha = 2) between landmarks ``est`` (M, 2) and beacons ``truth`` (B, 2) [m],
    cut-off ``c`` [m], order ``p``."""
    est = np.asarray(est, dtype=float).reshape(-1, 2)
    truth = np.asarray(truth, dtype=float).reshape(-1, 2)
    if not (c > 0 and p >= 1):
        raise ValueError(f"gospa: expected c > 0 and p >= 1, got c = {c}, p = {p}")
    d = np.hypot(est[:, None, 0] - truth[None, :, 0], est[:, None, 1] - truth[None, :, 1])
    pairs = [(i, j) for i, j in min_cost_assignment(np.minimum(d, c) ** p) if d[i, j] < c]
    loc = float(sum(d[i, j] ** p for i, j in pairs))
    missed = truth.shape[0] - len(pairs)
    false = est.shape[0] - len(pairs)
    value = (loc + c**p / 2.0 * (missed + false)) ** (1.0 / p)
    return Gospa(value, loc, missed, false, tuple(pairs))


def joint_error(mean: np.ndarray, ids: Sequence[int], true_pose: np.ndarray,
                true_xy: Mapping[int, tuple[float, float]]) -> np.ndarray:
    """Truth minus estimate over ``[x, y, theta, m1x, m1y, ...]`` (heading wrapped); the
    landmarks' truths looked up by their beacon ID."""
    truth = np.concatenate([np.asarray(true_pose, dtype=float)[:3],
                            np.array([true_xy[int(i)] for i in ids], dtype=float).reshape(-1)])
    e = truth - np.asarray(mean, dtype=float)
    e[2] = wrap(e[2])
    return e


def joint_nees(mean: np.ndarray, cov: np.ndarray, ids: Sequence[int], true_pose: np.ndarray,
               true_xy: Mapping[int, tuple[float, float]]) -> float:
    """``e^T P^-1 e`` of a joint pose-and-map Gaussian; chi-square with 3 + 2M dof when the
    filter is consistent."""
    e = joint_error(mean, ids, true_pose, true_xy)
    return float(e @ np.linalg.solve(np.asarray(cov, dtype=float), e))


def joint_anees_band(runs: int, dof: int, confidence: float = 0.95) -> tuple[float, float]:
    """The two-sided band the average NEES over ``runs`` independent runs, divided by
    ``dof``, lies in with probability ``confidence`` (sum is chi-square with runs x dof)."""
    k = runs * dof
    lo = chi2_quantile((1 - confidence) / 2, k) / k
    hi = chi2_quantile((1 + confidence) / 2, k) / k
    return lo, hi
