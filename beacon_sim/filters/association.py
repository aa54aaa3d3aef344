"""Data association: which beacon of a known map each reading without an ID came from.

Unknown correspondence (seed 003: "doors in a corridor look alike"): a beacon sensor reports
bearings ``[b]`` or range-bearings ``[r, b]`` (rows of ``z``, shape (m, d), d = 1 or 2, in the
robot frame, [m, rad]) but not which beacon each row belongs to. This module answers that for
a Gaussian pose belief (mean (3,), covariance P (3, 3) [m, m, rad]) and for a particle set
(poses (N, 3)). Beacons are given as positions ``beacon_xy`` (n, 2) [m] in the world frame and
their ``beacon_ids`` (n,).

- :func:`linearise`: every reading against every beacon: the innovation ``nu_ij = z_i - h_j``
  (bearing residual wrapped to [-pi, pi)), ``H_j`` (d, 3), ``S_j = H_j P H_j^T + R`` and the
  squared Mahalanobis distance ``d2_ij = nu_ij^T S_j^-1 nu_ij``.
- :func:`gate`: the chi-square quantile a distance must not exceed (``prob`` of the true
  pairings pass, with d degrees of freedom).
- :func:`nearest_neighbour`: greedy nearest neighbour inside the gate.
- :func:`jcbb`: joint compatibility branch and bound (Neira and Tardos 2001), with a node cap
  and a fallback to nearest neighbour; its search, :func:`jcbb_search`, is the one JCBB of
  the package (EKF-SLAM's full state and FastSLAM's particles call it with their own
  joint test; :func:`linearised_landmarks` is a particle's linearisation).
- :func:`joint_nis`: the joint NIS of a pairing, with the cross terms the shared pose error
  induces between readings.
- :func:`particle_ml_association`: per particle and reading, the most likely beacon and its
  log-likelihood, vectorised over particles (for the particle filter).

The result of the Gaussian methods is an :class:`Association`: for each reading, the ID of the
beacon it was given to, or None (clutter, or no beacon compatible with it).

The filters' hooks (each filter calls one at the start of its update and
returns at once when every sensor tells its IDs): :func:`associate_gaussian` (EKF, UKF: NN or
JCBB at the predicted belief, then a labeled reading), :func:`particle_loglik` (per-particle
maximum likelihood), :func:`grid_mixture` (the histogram's mixture over the beacons). What
they chose is reported by ``FilterBase.associations()``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Protocol

import numpy as np

from beacon_sim.core import measurement_models as mm
from beacon_sim.core.angles import wrap, wrap_into
from beacon_sim.core.clutter import UNKNOWN_ID
from beacon_sim.core.metrics import chi2_quantile
from beacon_sim.core.sensor_kinds import dims
from beacon_sim.core.types import Measurement
from beacon_sim.filters.base import FilterContext, FilterError

#: The reading kinds that need association and the width of one row.
READING_DIMS = {k: dims(k) for k in ("bearing", "range_bearing")}

#: Default probability that a true pairing passes the gate (and the joint test).
GATE_PROB = 0.99

#: Default cap on the nodes JCBB may visit before it gives up and returns nearest neighbour.
#: A node costs about 10-40 us (one batched 3 x 3 solve for all its candidates; measured on a
#: loaded 2-core machine), so the cap bounds a tick's search at roughly 20-80 ms. Typical ticks
#: take tens of nodes; 15 readings + 3 clutter among 40 beacons with a 1 m position
#: uncertainty, ~850 (``benchmarks/bench_association.py``).
MAX_NODES = 2_000

#: A pairing: (reading index, beacon row index) pairs, in reading order.
Pairing = tuple[tuple[int, int], ...]


@dataclass(frozen=True)
class Association:
    """For each reading, the beacon it was given to (what ``associations()`` reports).

    Attributes
    ----------
    beacon_ids : tuple of (int or None), length m
        The ID of the beacon each reading was associated with; None: no beacon (clutter).
    method : str
        ``"nn"``, ``"jcbb"``, or ``"nn-fallback"`` (JCBB hit its node cap: nearest neighbour).
    joint_nis : float
        Joint NIS of the pairs (with the cross terms; 0 when nothing is paired).
    dof : int
        Degrees of freedom of ``joint_nis``: paired readings times the reading width.
    nodes : int
        Search nodes JCBB visited (0 for nearest neighbour).
    """

    beacon_ids: tuple[int | None, ...]
    method: str
    joint_nis: float = 0.0
    dof: int = 0
    nodes: int = 0

    @property
    def n_paired(self) -> int:
        """How many readings were given a beacon."""
        return sum(b is not None for b in self.beacon_ids)


@dataclass(frozen=True, eq=False)
class Linearised:
    """Every reading against every beacon, linearised at the mean.

    Attributes
    ----------
    kind : str
        ``"bearing"`` or ``"range_bearing"``.
    nu : ndarray, shape (m, n, d)
        Innovations ``z_i - h_j(mean)`` [m, rad]; bearing residuals wrapped.
    H : ndarray, shape (n, d, 3)
        Jacobian of beacon j's expected reading with respect to the pose.
    P : ndarray, shape (3, 3)
        Pose covariance [m^2, m^2, rad^2].
    r : ndarray, shape (d,)
        Reading noise variances (diagonal R) [m^2, rad^2].
    S : ndarray, shape (n, d, d)
        Innovation covariance of one reading paired with beacon j.
    d2 : ndarray, shape (m, n)
        Squared Mahalanobis distances; ``inf`` where undefined (beacon on the robot).
    Z : ndarray, shape (n, d, d), optional
        Each candidate's own noise when it is not just ``diag(r)``: a mapped landmark's
        ``Hm C Hm^T + R`` (FastSLAM, :func:`linearised_landmarks`). None: ``diag(r)``.
    """

    kind: str
    nu: np.ndarray
    H: np.ndarray
    P: np.ndarray
    r: np.ndarray
    S: np.ndarray
    d2: np.ndarray
    Z: np.ndarray | None = None

    @property
    def dim(self) -> int:
        """Width d of one reading."""
        return READING_DIMS[self.kind]


def _check(kind: str, z: np.ndarray, beacon_xy: np.ndarray, reading_std: Sequence[float]
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    if kind not in READING_DIMS:
        raise ValueError(f"association: kind {kind!r} is not one of {sorted(READING_DIMS)}")
    d = READING_DIMS[kind]
    z = np.asarray(z, dtype=float).reshape(-1, d)
    xy = np.asarray(beacon_xy, dtype=float).reshape(-1, 2)
    r = np.asarray(reading_std, dtype=float).reshape(-1) ** 2
    if r.shape != (d,):
        raise ValueError(f"association: reading_std for {kind!r} needs {d} values, got {r.size}")
    if not np.all(np.isfinite(r) & (r > 0.0)):
        raise ValueError(f"association: reading_std must be finite and > 0, got {list(np.sqrt(r))}")
    return z, xy, r


def expected(kind: str, pose: np.ndarray, beacon_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Expected readings (n, d) and their Jacobians (n, d, 3) of every beacon from ``pose``."""
    if kind == "bearing":
        return mm.bearing(pose, beacon_xy)[:, None], mm.bearing_jacobian(pose, beacon_xy)[:, None, :]
    return mm.range_bearing(pose, beacon_xy), mm.range_bearing_jacobian(pose, beacon_xy)


def residual(kind: str, z: np.ndarray, zhat: np.ndarray) -> np.ndarray:
    """``z - zhat`` with the bearing column (the last one) wrapped to [-pi, pi)."""
    nu = np.asarray(z, dtype=float) - np.asarray(zhat, dtype=float)
    nu[..., -1] = wrap(nu[..., -1])
    return nu


def linearise(kind: str, z: np.ndarray, mean: np.ndarray, cov: np.ndarray,
              beacon_xy: np.ndarray, reading_std: Sequence[float]) -> Linearised:
    """Innovations, S and squared Mahalanobis distances of every (reading, beacon) pair.

    Parameters
    ----------
    kind : ``"bearing"`` or ``"range_bearing"``
    z : ndarray, shape (m, d) [m, rad]
    mean : ndarray, shape (3,) [m, m, rad]
    cov : ndarray, shape (3, 3)
    beacon_xy : ndarray, shape (n, 2) [m]
    reading_std : the sensor's ``reading_std()``: ``[sb]`` or ``[sr, sb]`` [m, rad]
    """
    z, xy, r = _check(kind, z, beacon_xy, reading_std)
    mean = np.asarray(mean, dtype=float)
    P = np.asarray(cov, dtype=float)
    if mean.shape != (3,) or P.shape != (3, 3):
        raise ValueError(f"association: mean must have shape (3,) and cov (3, 3), got {mean.shape} "
                         f"and {P.shape}")
    with np.errstate(divide="ignore", invalid="ignore"):
        zhat, H = expected(kind, mean, xy)
        nu = residual(kind, z[:, None, :], zhat[None, :, :])
        S = H @ P @ H.transpose(0, 2, 1) + np.diag(r)
        ok = np.all(np.isfinite(S), axis=(1, 2))
        S_safe = np.where(ok[:, None, None], S, np.eye(r.size))
        w = np.linalg.solve(S_safe[None, :, :, :], nu[..., None])[..., 0]
        d2 = np.einsum("mnd,mnd->mn", nu, w)
    d2 = np.where(ok[None, :] & np.isfinite(d2), d2, np.inf)
    return Linearised(kind, nu, H, P, r, S, d2)


def linearised_landmarks(kind: str, nu: np.ndarray, H: np.ndarray, P: np.ndarray, Z: np.ndarray,
                         R: np.ndarray, d2: np.ndarray | None = None) -> Linearised:
    """A linearisation against uncertain landmarks (one FastSLAM particle's map): innovations
    ``nu`` (m, n, d), pose Jacobians ``H`` (n, d, 3), pose covariance ``P`` (3, 3) and each
    landmark's ``Z_j = Hm C_j Hm^T + R`` (n, d, d) (R (d, d) the reading noise), so
    ``S_j = H_j P H_j^T + Z_j``. Landmarks are independent of each other given the pose, so
    only the pose error is shared between readings. ``d2`` (m, n) when the caller has it
    (``inf`` for a landmark to leave out)."""
    S = H @ P @ H.transpose(0, 2, 1) + Z
    if d2 is None:
        with np.errstate(divide="ignore", invalid="ignore"):
            ok = np.all(np.isfinite(S), axis=(1, 2))
            S_safe = np.where(ok[:, None, None], S, np.eye(S.shape[-1]))
            w = np.linalg.solve(S_safe[None, :, :, :], nu[..., None])[..., 0]
            d2 = np.where(ok[None, :], np.einsum("mnd,mnd->mn", nu, w), np.inf)
        d2 = np.where(np.isfinite(d2), d2, np.inf)
    return Linearised(kind, nu, H, P, np.diag(np.asarray(R, dtype=float)).copy(), S, d2, Z)


@lru_cache(maxsize=256)
def gate(prob: float, dof: int) -> float:
    """The chi-square ``prob`` quantile with ``dof`` degrees of freedom (a squared
    Mahalanobis distance at or below it passes)."""
    return chi2_quantile(prob, dof)


def joint_nis(lin: Linearised, pairing: Pairing) -> float:
    """Joint NIS of a pairing [(reading i, beacon row j), ...].

    The innovations of the paired readings are stacked into one vector ``nu`` (k d,) and
    their Jacobians into ``H`` (k d, 3); ``S = H P H^T + R`` over the stack is full, not
    block diagonal: its off-diagonal blocks ``H_a P H_b^T`` are the correlation the one
    shared pose error puts between the readings. ``NIS = nu^T S^-1 nu``.
    """
    if not pairing:
        return 0.0
    rows = np.array([i for i, _ in pairing])
    cols = np.array([j for _, j in pairing])
    nu = lin.nu[rows, cols].reshape(-1)
    H = lin.H[cols].reshape(-1, 3)
    if lin.Z is None:
        D = np.diag(np.tile(lin.r, len(pairing)))
    else:  # block diagonal: each landmark's own noise, independent of the others'
        d = lin.dim
        D = np.zeros((d * len(pairing), d * len(pairing)))
        for k, j in enumerate(cols):
            D[k * d:(k + 1) * d, k * d:(k + 1) * d] = lin.Z[j]
    S = H @ lin.P @ H.T + D
    if not np.all(np.isfinite(S)):
        return math.inf
    try:
        value = float(nu @ np.linalg.solve(S, nu))
    except np.linalg.LinAlgError:
        return math.inf
    return value if math.isfinite(value) else math.inf


def _check_ids(lin: Linearised, beacon_ids: np.ndarray) -> None:
    if len(beacon_ids) != lin.H.shape[0]:
        raise ValueError(f"association: {len(beacon_ids)} beacon IDs for {lin.H.shape[0]} beacons")


def _association(lin: Linearised, pairing: Pairing, beacon_ids: np.ndarray, method: str,
                 nodes: int = 0) -> Association:
    ids: list[int | None] = [None] * lin.nu.shape[0]
    for i, j in pairing:
        ids[i] = int(beacon_ids[j])
    return Association(tuple(ids), method, joint_nis(lin, pairing), lin.dim * len(pairing), nodes)


def _nn_pairing(lin: Linearised, prob: float) -> Pairing:
    g = gate(prob, lin.dim)
    cand = np.argwhere(lin.d2 <= g)
    # Ascending distance; ties broken by reading then beacon index (stable: deterministic).
    order = np.lexsort((cand[:, 1], cand[:, 0], lin.d2[cand[:, 0], cand[:, 1]]))
    used_r: set[int] = set()
    used_b: set[int] = set()
    pairs = []
    for i, j in cand[order]:
        if int(i) not in used_r and int(j) not in used_b:
            used_r.add(int(i))
            used_b.add(int(j))
            pairs.append((int(i), int(j)))
    return tuple(sorted(pairs))


def nearest_neighbour(lin: Linearised, beacon_ids: np.ndarray, prob: float = GATE_PROB
                      ) -> Association:
    """Greedy nearest neighbour with a Mahalanobis gate.

    Among all (reading, beacon) pairs with ``d2 <= gate(prob, d)``, the closest pair is taken
    first, then the closest of the rest whose reading and beacon are both still free, and so
    on: each reading gets at most one beacon and each beacon at most one reading. Greedy, not
    the optimal assignment; and each test is one reading's alone, blind to the pose error the
    readings share (what :func:`jcbb` adds). Readings left over get None.
    """
    _check_ids(lin, beacon_ids)
    return _association(lin, _nn_pairing(lin, prob), beacon_ids, "nn")


class _NodeCap(Exception):
    """JCBB visited more nodes than allowed."""


class JointInformation:
    """The joint NIS of growing pairings in O(1) per added pair, for the JCBB search.

    Woodbury's identity turns the stacked ``nu^T (H P H^T + D)^-1 nu`` (``D`` block diagonal:
    each pair's own noise) into ``a - b^T (I + P M)^-1 P b`` with the sums over the pairs
    ``a = nu^T D^-1 nu`` (scalar), ``b = H^T D^-1 nu`` (3,) and ``M = H^T D^-1 H`` (3, 3):
    adding a pair adds its terms and costs one 3 x 3 solve, whatever the number of pairs.
    Valid for a singular P too (``I + P M`` is invertible for P, M positive semi-definite).
    :func:`joint_nis` is the direct form, used for the reported figure; the tests hold the two
    together.

    ``a`` (m, n), ``b`` (m, n, 3), ``M`` (n, 3, 3): every reading i against every candidate j;
    ``P`` (3, 3) the covariance of the shared pose. Build it from a :class:`Linearised`
    (:meth:`of`) or directly from these sums (FastSLAM computes them for all its particles
    at once and hands each particle its slice).
    """

    def __init__(self, P: np.ndarray, a: np.ndarray, b: np.ndarray, M: np.ndarray):
        self.P, self.a, self.b, self.M = P, a, b, M
        self.eye = np.eye(3)

    @classmethod
    def of(cls, lin: Linearised) -> JointInformation:
        """The sums of a linearisation: ``D = R`` (diagonal) or, when ``lin.Z`` is given, each
        candidate's own ``Z_j`` (reading noise plus the landmark's uncertainty)."""
        if lin.Z is None:
            w = 1.0 / lin.r  # (d,)
            a = np.einsum("mnd,d,mnd->mn", lin.nu, w, lin.nu)  # (m, n)
            b = np.einsum("ndk,d,mnd->mnk", lin.H, w, lin.nu)  # (m, n, 3)
            M = np.einsum("ndk,d,ndl->nkl", lin.H, w, lin.H)  # (n, 3, 3)
            return cls(lin.P, a, b, M)
        return cls(lin.P, *information_sums(lin.nu, lin.H, lin.Z))

    def start(self) -> tuple[float, np.ndarray, np.ndarray]:
        """The sums of the empty pairing."""
        return (0.0, np.zeros(3), np.zeros((3, 3)))

    def grow(self, state: tuple[float, np.ndarray, np.ndarray], i: int, cols: list[int]
             ) -> tuple[list[tuple[float, np.ndarray, np.ndarray]], np.ndarray]:
        """The sums with pair (i, j) added, for every j of ``cols`` at once, and the joint NIS
        of each grown pairing (c,) (``inf`` where undefined)."""
        a = state[0] + self.a[i, cols]
        b = state[1] + self.b[i, cols]
        M = state[2] + self.M[cols]
        Pb = b @ self.P  # (c, 3): P b for each (P symmetric)
        with np.errstate(invalid="ignore", over="ignore"):
            try:
                x = np.linalg.solve(self.eye + self.P @ M, Pb[..., None])[..., 0]
                value = a - np.einsum("ck,ck->c", b, x)
            except np.linalg.LinAlgError:
                value = np.full(len(cols), np.inf)
        states = [(float(a[c]), b[c], M[c]) for c in range(len(cols))]
        return states, np.where(np.isfinite(value), value, np.inf)


def information_sums(nu: np.ndarray, H: np.ndarray, Z: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:class:`JointInformation`'s per-pair terms with a full noise ``Z_j`` per candidate,
    for any leading batch axes (FastSLAM: one per particle).

    nu (..., m, n, d), H (..., n, d, 3), Z (..., n, d, d) -> a (..., m, n), b (..., m, n, 3),
    M (..., n, 3, 3). A candidate whose Z is not finite or not invertible gets ``a = inf``.
    """
    ok = np.all(np.isfinite(Z), axis=(-2, -1))
    Zs = np.where(ok[..., None, None], Z, np.eye(Z.shape[-1]))
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        W = np.linalg.inv(Zs)
        a = np.einsum("...mnd,...nde,...mne->...mn", nu, W, nu)
        WH = W @ H
        b = np.einsum("...nek,...mne->...mnk", WH, nu)
        M = np.einsum("...ndk,...ndl->...nkl", H, WH)
    a = np.where(ok[..., None, :] & np.isfinite(a), a, np.inf)
    return a, np.nan_to_num(b), np.nan_to_num(M)


class JointTest(Protocol):
    """What the JCBB search asks of a state: the empty pairing's ``start()`` state, and
    ``grow(state, i, cols) -> (states, values)``, the state and the joint NIS of the pairing
    with (i, j) added, for each j of cols. :class:`JointInformation` is one (a pose-only
    Gaussian, or a particle's pose proposal with its landmarks); EKF-SLAM's full-state test
    (``ekf_slam.FullStateJoint``) another."""

    def start(self) -> Any: ...

    def grow(self, state: Any, i: int, cols: list[int]) -> tuple[Sequence[Any], np.ndarray]: ...


def jcbb_search(d2: np.ndarray, dims: Sequence[int], joint: JointTest, prob: float = GATE_PROB,
                max_nodes: int = MAX_NODES) -> tuple[Pairing | None, float, int]:
    """The branch and bound of joint compatibility (Neira and Tardos 2001), the one home of
    JCBB (the known-map :func:`jcbb`, EKF-SLAM and FastSLAM's per-particle option call it).

    Parameters
    ----------
    d2 : ndarray, shape (m, n)
        Each reading's squared Mahalanobis distance to each candidate (``inf``: impossible).
    dims : the width of each reading (its degrees of freedom)
    joint : a :class:`JointTest` (``start``, ``grow``)
    prob : a candidate is tried only inside ``gate(prob, dims[i])``; a pairing of k readings
        is kept only if its joint NIS is inside ``gate(prob, sum of their dims)``.
    max_nodes : past this many search nodes the search stops.

    Returns
    -------
    pairing : the most pairs; among as many, the lowest joint NIS (sorted by reading); None
        when the search passed ``max_nodes``.
    nis : its joint NIS
    nodes : search nodes visited
    """
    m_all = d2.shape[0]
    candidates = [[int(j) for j in np.argsort(d2[i], kind="stable") if d2[i, j] <= gate(prob, int(dims[i]))]
                  for i in range(m_all)]
    # Most constrained first: readings with the fewest candidates branch least near the root.
    # Readings with none are clutter whatever happens and are left out of the search.
    order = sorted((i for i, c in enumerate(candidates) if c), key=lambda i: (len(candidates[i]), i))
    m = len(order)
    best: list = [(), 0.0]  # pairing, its joint NIS
    nodes = 0

    def visit(k: int, pairing: Pairing, used: frozenset[int], state: Any, dof: int,
              nis_value: float) -> None:
        nonlocal nodes
        nodes += 1
        if nodes > max_nodes:
            raise _NodeCap
        if len(pairing) + (m - k) < len(best[0]):
            return  # cannot reach the best count
        if k == m:
            if len(pairing) > len(best[0]) or nis_value < best[1]:
                best[0], best[1] = pairing, nis_value
            return
        i = order[k]
        free = [j for j in candidates[i] if j not in used]
        if free:
            states, values = joint.grow(state, i, free)
            d = int(dims[i])
            limit = gate(prob, dof + d)
            for c, j in enumerate(free):
                if values[c] <= limit:
                    visit(k + 1, (*pairing, (i, j)), used | {j}, states[c], dof + d, float(values[c]))
        visit(k + 1, pairing, used, state, dof, nis_value)  # reading i is clutter

    try:
        visit(0, (), frozenset(), joint.start(), 0, 0.0)
    except _NodeCap:
        return None, math.inf, nodes - 1
    return tuple(sorted(best[0])), float(best[1]), nodes


def jcbb(lin: Linearised, beacon_ids: np.ndarray, prob: float = GATE_PROB,
         max_nodes: int = MAX_NODES) -> Association:
    """Joint compatibility branch and bound (Neira and Tardos 2001) on a known map.

    Depth-first over the readings, those with the fewest individually compatible beacons
    first (readings with none are clutter and skipped). At reading i, each beacon that is individually
    compatible with it (``d2 <= gate(prob, d)``, nearest first) and not yet used is tried; the
    branch is kept only if the whole pairing so far stays jointly compatible
    (``joint_nis <= gate(prob, d k)`` for k pairs, with the cross terms). Then the branch that
    leaves reading i unpaired (clutter) is tried. A branch is cut when even pairing every
    reading left could not reach the best number of pairs found. The answer: the most
    pairs; among pairings with as many, the lowest joint NIS (:func:`jcbb_search`).

    Bounded: after ``max_nodes`` nodes the search stops and the result is
    :func:`nearest_neighbour`'s, with ``method = "nn-fallback"`` (so a tick never stalls).
    """
    _check_ids(lin, beacon_ids)
    pairing, _, nodes = jcbb_search(lin.d2, [lin.dim] * lin.nu.shape[0], JointInformation.of(lin),
                                    prob, max_nodes)
    if pairing is None:
        return _association(lin, _nn_pairing(lin, prob), beacon_ids, "nn-fallback", max_nodes)
    return _association(lin, pairing, beacon_ids, "jcbb", nodes)


def particle_ml_association(kind: str, z: np.ndarray, poses: np.ndarray, beacon_xy: np.ndarray,
                            reading_std: Sequence[float], prob: float | None = None
                            ) -> tuple[np.ndarray, np.ndarray]:
    """Per particle and reading, the maximum-likelihood beacon and its log-likelihood.

    Each particle is a pose with no uncertainty of its own, so the likelihood of reading i
    from beacon j is the Gaussian ``N(nu_ij; 0, R)`` (diagonal R, bearing residual wrapped).
    Readings are associated independently (two readings may pick the same beacon), as in
    FastSLAM's per-particle maximum likelihood.

    Parameters
    ----------
    kind, z, beacon_xy, reading_std : as in :func:`linearise`
    poses : ndarray, shape (N, 3) [m, m, rad]
    prob : float, optional
        When given, a best beacon whose squared distance ``nu^T R^-1 nu`` exceeds
        ``gate(prob, d)`` is rejected: its index becomes -1 (the log-likelihood stays the
        best beacon's, for the caller to replace by a clutter density if it wants).

    Returns
    -------
    best : ndarray of int, shape (N, m)
        Row index into ``beacon_xy`` of each particle's choice for each reading (-1: gated out).
    loglik : ndarray, shape (N, m)
        ``log N(nu; 0, R)`` of that choice (includes the Gaussian's normalising constant).
    """
    best, d2_best = _particle_d2(kind, z, poses, beacon_xy, reading_std)
    r = _check(kind, z, beacon_xy, reading_std)[2]
    log_norm = -0.5 * (r.size * math.log(2.0 * math.pi) + float(np.sum(np.log(r))))
    loglik = log_norm - 0.5 * d2_best
    if prob is not None:
        best = np.where(d2_best <= gate(prob, r.size), best, -1)
    return best, loglik


def _particle_d2(kind: str, z: np.ndarray, poses: np.ndarray, beacon_xy: np.ndarray,
                 reading_std: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """Per particle and reading, the nearest beacon row (N, m) and its squared distance
    ``nu^T R^-1 nu`` (N, m) (``inf`` when there is no beacon)."""
    z, xy, r = _check(kind, z, beacon_xy, reading_std)
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    n_part, m, n = poses.shape[0], z.shape[0], xy.shape[0]
    if n == 0 or m == 0:
        return np.full((n_part, m), -1, dtype=int), np.full((n_part, m), np.inf)
    # Reading by reading on (N, n) arrays kept for the whole call: a working set that stays in
    # cache and no fresh (N, m, n) arrays (each one a page fault per 4 KB); the arithmetic is
    # the one it replaced, element by element, so the bits are the same.
    bear = mm.bearing_many(poses, xy)
    rng = mm.range_many(poses, xy) if kind == "range_bearing" else None
    d2 = np.empty((n_part, n))
    tmp = np.empty((n_part, n))
    inv_b, inv_r = 1.0 / r[-1], 1.0 / r[0]
    best = np.empty((n_part, m), dtype=np.intp)
    d2_best = np.empty((n_part, m))
    rows = np.arange(n_part)
    for i in range(m):
        np.subtract(z[i, -1], bear, out=d2)
        wrap_into(d2, tmp)
        np.multiply(d2, d2, out=d2)
        d2 *= inv_b
        if rng is not None:
            np.subtract(z[i, 0], rng, out=tmp)
            tmp *= tmp
            tmp *= inv_r
            d2 += tmp
        d2[np.isnan(d2)] = np.inf  # a reading or pose that is not a number fits no beacon
        b = np.argmin(d2, axis=1)  # first minimum: ties go to the lower beacon row
        best[:, i] = b
        d2_best[:, i] = d2[rows, b]
    return best, d2_best


# -- Wiring into the filters -----------------------------------------------------------------
# Each filter calls one hook at the start of its update (docs/association.md, "In the
# filters"); the state lives on the filter as ``_association`` and ``FilterBase.associations``
# reports it. Known-correspondence runs take the first branch of every hook and are unchanged.

#: The Gaussian filters' association methods (parameter ``association``).
METHODS = ("nn", "jcbb")

#: The parameters the EKF and the UKF take for unknown correspondence, with their defaults:
#: the method, its gate's probability, the factor on the innovation covariance S the gate
#: and the joint test use (1: as the filter's update), and the share of the gated beacons'
#: likelihood the nearest beacon's group must hold for a reading to be associated, else it
#: is refused as ambiguous (dropped as clutter; :func:`refuse_ambiguous`; 0: off).
GAUSSIAN_PARAMS = {"association": "nn", "association_prob": GATE_PROB, "association_inflation": 1.0,
                   "unambiguous_share": 0.0}

#: The share of unlabeled readings the particle and histogram filters take as clutter at
#: least (their likelihood's floor): a reading no beacon explains costs a bounded amount.
MIN_CLUTTER_SHARE = 0.01


def is_unlabeled(m: Measurement) -> bool:
    """Whether a reading carries no beacon IDs (every entry ``UNKNOWN_ID``): beacon kinds only."""
    return m.kind in READING_DIMS and len(m) > 0 and bool(np.all(np.asarray(m.beacon_ids) == UNKNOWN_ID))


class _Wiring:
    """One filter's association state: the map, whether any sensor is unlabeled, and what
    the last update associated (``last``: sensor name -> beacon ID or None per row)."""

    def __init__(self, ctx: FilterContext, method: str = "nn", prob: float = GATE_PROB,
                 inflation: float = 1.0, share: float = 0.0):
        if method not in METHODS:
            raise FilterError(f"{ctx.name}: association = {method!r}: expected one of "
                              + ", ".join(map(repr, METHODS)))
        if not 0.0 < prob < 1.0:
            raise FilterError(f"{ctx.name}: association_prob = {prob!r}: expected a probability in (0, 1)")
        if not (isinstance(inflation, int | float) and math.isfinite(inflation) and inflation >= 1.0):
            raise FilterError(f"{ctx.name}: association_inflation = {inflation!r}: expected a number >= 1")
        if not (isinstance(share, int | float) and 0.0 <= share < 1.0):
            raise FilterError(f"{ctx.name}: unambiguous_share = {share!r}: expected a share in [0, 1)")
        self.inflation = float(inflation)
        self.share = float(share)
        self.ctx = ctx
        self.unknown = any(s.correspondence != "known" for s in ctx.sensors)
        self.xy = ctx.world.beacon_xy
        self.ids = ctx.world.beacon_ids
        self.method = method
        self.prob = float(prob)
        self.last: dict[str, tuple[int | None, ...]] = {}
        self.readings: list[Measurement] = []  # the last update's unlabeled readings

    def report(self, flt: Any) -> dict[str, tuple[int | None, ...]]:
        return dict(self.last)


def attach(flt: Any) -> None:
    """Give a Gaussian filter (EKF, UKF) its association state from ``flt.params``
    (``association``, ``association_prob``); FilterError for a bad value. Call in __init__."""
    p = flt.params
    flt._association = _Wiring(flt.ctx, p.get("association", "nn"), p.get("association_prob", GATE_PROB),
                               p.get("association_inflation", 1.0), p.get("unambiguous_share", 0.0))


def inflated(lin: Linearised, factor: float) -> Linearised:
    """``lin`` with every innovation covariance ``S`` (and the pose covariance and reading
    noise it is made of) multiplied by ``factor``: the distances ``d2`` divided by it. For
    association only: a wider gate and joint test for errors the update's model leaves out
    (real data's late readings, range bias); the update itself keeps its own ``S``."""
    if factor == 1.0:
        return lin
    return Linearised(lin.kind, lin.nu, lin.H, lin.P * factor, lin.r * factor, lin.S * factor,
                      lin.d2 / factor, None if lin.Z is None else lin.Z * factor)


def refuse_ambiguous(lin: Linearised, prob: float, share: float) -> Linearised:
    """``lin`` with every *ambiguous* reading made compatible with no beacon (its row of
    ``d2`` set to ``inf``, so it is dropped as clutter).

    The beacons a reading is compared with are those inside its gate (``d2 <= gate(prob,
    d)``); each has the Gaussian likelihood ``exp(-d2 / 2) / sqrt(det S)`` (equal priors).
    The nearest beacon's *group* is the gated beacons the sensor cannot tell from it: their
    expected readings differ from the nearest's by at most the gate under the reading noise
    R alone (``dz^T R^-1 dz <= gate``, ``dz`` the difference of the two expected readings,
    bearing wrapped). The reading is ambiguous when its nearest beacon's group holds less
    than ``share`` of the gated beacons' summed likelihood: a beacon the sensor could tell
    apart fits it nearly as well, and only the pose's uncertainty makes both fit. The nearest
    would then be a guess that, when wrong, pulls the pose towards the wrong beacon and makes
    the next wrong pairing likelier (real data after a long blind stretch: a heading 20
    degrees off, readings given a beacon a metre from theirs). A group of landmarks 18-25 cm
    apart seen from metres counts as one: the nearest is kept, wrong by at most their
    distance."""
    g = gate(prob, lin.dim)
    m, n = lin.d2.shape
    if n < 2 or m == 0:
        return lin
    gated = lin.d2 <= g                                     # (m, n)
    if not (gated.sum(axis=1) >= 2).any():
        return lin
    rows = np.arange(m)
    best = np.argmin(lin.d2, axis=1)
    dz = lin.nu[rows, best][:, None, :] - lin.nu            # h_j - h_best, (m, n, d)
    dz[..., -1] = wrap(dz[..., -1])
    alike = np.einsum("mnd,d->mn", dz * dz, 1.0 / lin.r) <= g
    with np.errstate(divide="ignore", invalid="ignore"):
        logdet = np.linalg.slogdet(lin.S)[1]                # (n,)
        like = np.where(gated, np.exp(-0.5 * (lin.d2 - lin.d2[rows, best][:, None])
                                      - 0.5 * (logdet[None, :] - logdet[best][:, None])), 0.0)
    total = like.sum(axis=1)
    ambiguous = gated[rows, best] & (np.where(alike, like, 0.0).sum(axis=1) < share * total)
    if not ambiguous.any():
        return lin
    d2 = lin.d2.copy()
    d2[ambiguous] = np.inf
    return Linearised(lin.kind, lin.nu, lin.H, lin.P, lin.r, lin.S, d2, lin.Z)


def associate_gaussian(flt: Any, measurements: Sequence[Measurement]) -> Sequence[Measurement]:
    """The EKF's and UKF's hook: each unlabeled reading associated at the predicted belief
    (``flt.mean``, ``flt.cov``) by nearest neighbour or JCBB; returned as a labeled reading
    of the rows that got a beacon (the others are dropped as clutter). Labeled readings pass
    unchanged, and so does everything when no sensor has unknown correspondence."""
    w: _Wiring = flt._association
    if not w.unknown:
        return measurements
    w.last = {}
    out: list[Measurement] = []
    for m in measurements:
        if not is_unlabeled(m):
            out.append(m)
            continue
        lin = inflated(linearise(m.kind, m.z, flt.mean, flt.cov, w.xy,
                                 flt.ctx.sensor(m.sensor).reading_std()), w.inflation)
        if w.share > 0.0:
            lin = refuse_ambiguous(lin, w.prob, w.share)
        found = (jcbb if w.method == "jcbb" else nearest_neighbour)(lin, w.ids, w.prob)
        w.last[m.sensor] = found.beacon_ids
        keep = [i for i, b in enumerate(found.beacon_ids) if b is not None]
        if keep:
            out.append(Measurement(m.sensor, m.kind, np.asarray(m.z)[keep],
                                   np.array([found.beacon_ids[i] for i in keep], dtype=int)))
    return out


class _ParticleWiring(_Wiring):
    """The particle filter's state: each particle's choice per reading of the last update."""

    def __init__(self, ctx: FilterContext):
        super().__init__(ctx)
        self.choices: dict[str, np.ndarray] = {}  # sensor -> (N, m) beacon rows, -1 clutter

    def report(self, flt: Any) -> dict[str, tuple[int | None, ...]]:
        """Per reading, the beacon the particles chose with the most weight (None when the
        weight of those calling it clutter is larger)."""
        w = np.asarray(flt.weights(), dtype=float)
        out: dict[str, tuple[int | None, ...]] = {}
        for name, best in self.choices.items():
            if best.shape[0] != w.size:
                continue  # the set changed since (resampled): nothing to say
            row: list[int | None] = []
            for i in range(best.shape[1]):
                votes = np.bincount(best[:, i] + 1, weights=w, minlength=len(self.ids) + 1)
                j = int(np.argmax(votes)) - 1
                row.append(None if j < 0 else int(self.ids[j]))
            out[name] = tuple(row)
        return out


def particle_loglik(flt: Any, m: Measurement, ll: np.ndarray) -> int:
    """The particle filter's hook for an unlabeled reading: each particle takes, for each
    row, its maximum-likelihood beacon (:func:`particle_ml_association`) and adds
    ``-0.5 min(d2, gate)`` to ``ll`` (n,): a row no beacon explains within the gate counts as
    clutter, a bounded cost. Returns the number of scalar readings (as ``_loglik``)."""
    w = flt.__dict__.get("_association")
    if not isinstance(w, _ParticleWiring):
        w = flt._association = _ParticleWiring(flt.ctx)
    n = flt.n
    spec = flt.ctx.sensor(m.sensor)
    poses = np.asarray(flt._P[:, :n], dtype=float).T
    best, d2 = _particle_d2(m.kind, m.z, poses, w.xy, spec.reading_std())
    g = gate(w.prob, READING_DIMS[m.kind])
    w.choices[m.sensor] = np.where(d2 <= g, best, -1)
    # Not counted by the filter's "lost" test (augmented MCL's random particles): with clutter
    # a row no beacon explains is the expected case, and a tick of clutter alone looked like
    # a kidnap; random particles then explained the clutter with some beacon and the cloud
    # left the truth (default with clutter_rate = 0.3: 2.6 m RMSE against 0.09 m).
    ll += -0.5 * np.minimum(d2, g).sum(axis=1)
    return int(np.asarray(m.z).size)


def particle_start(flt: Any) -> None:
    """Forget the last update's per-particle choices (called at each update's start)."""
    w = flt.__dict__.get("_association")
    if isinstance(w, _ParticleWiring):
        w.choices = {}


class _GridWiring(_Wiring):
    """The histogram filter's state: the last update's unlabeled readings, to report; and what
    :func:`grid_mixture` needs of each beacon on the x-y grid that never changes (the grid does
    not move), kept instead of worked out again on every reading."""

    def __init__(self, ctx: FilterContext):
        super().__init__(ctx)
        self._terms: dict[tuple[str, int], tuple[np.ndarray, ...]] = {}
        self._in_range: dict[tuple[int, float], np.ndarray] = {}
        self._scratch = np.empty(0)

    def beacon_terms(self, flt: Any, sensor: str, std: np.ndarray, b: int) -> tuple[np.ndarray, ...]:
        """Flat (nx ny,) arrays over the grid's cells: beacon ``b``'s range [m], the von
        Mises concentration kappa [1/rad^2] (bearing noise inflated by the bin and the cell),
        ``-kappa + log`` of its normaliser, and the cosine and sine of the beacon's direction:
        the arithmetic :func:`grid_mixture` did on each reading's cells, done once on all."""
        key = (sensor, b)
        got = self._terms.get(key)
        if got is None:
            r = flt._r[b].reshape(-1)
            cell_var = flt.cell ** 2 / 6.0
            kappa = 1.0 / (std[-1] ** 2 + flt.bin ** 2 / 12 + cell_var / np.maximum(r, flt.cell) ** 2)
            head = -kappa + 0.5 * np.log(kappa / (2.0 * math.pi))
            got = self._terms[key] = (r, kappa, head, flt._ca[b].reshape(-1), flt._sa[b].reshape(-1))
        return got

    def in_range(self, b: int, r: np.ndarray, reach: float) -> np.ndarray:
        """The flat indices of the cells within ``reach`` [m] of beacon ``b`` (kept)."""
        got = self._in_range.get((b, reach))
        if got is None:
            got = self._in_range[(b, reach)] = np.flatnonzero(r <= reach)
        return got

    def scratch(self, rows: int, cols: int) -> np.ndarray:
        """A (rows, cols) float array to work in, reused from call to call."""
        if self._scratch.size < rows * cols:
            self._scratch = np.empty(rows * cols)
        return self._scratch[: rows * cols].reshape(rows, cols)

    def report(self, flt: Any) -> dict[str, tuple[int | None, ...]]:
        """Per reading, the beacon most likely at the grid's most probable cell and heading
        (None when the clutter term is larger there)."""
        if not self.readings:
            return {}
        h, i, j = np.unravel_index(int(np.argmax(flt.grid)), flt.grid.shape)
        pose = np.array([flt.xc[i], flt.yc[j], float(flt.theta[h])])
        out: dict[str, tuple[int | None, ...]] = {}
        for m in self.readings:
            std = flt.ctx.sensor(m.sensor).reading_std()
            # the grid knows the pose to a cell and a heading bin: the filter's own inflation
            var = std ** 2 + (np.array([flt.cell ** 2 / 6.0, flt.bin ** 2 / 12.0])[-std.size:])
            best, d2 = _particle_d2(m.kind, m.z, pose[None, :], self.xy, np.sqrt(var))
            g = gate(self.prob, READING_DIMS[m.kind])
            out[m.sensor] = tuple(int(self.ids[b]) if d <= g else None
                                  for b, d in zip(best[0], d2[0], strict=True))
        return out


def grid_mixture(flt: Any, measurements: Sequence[Measurement], cos_th: np.ndarray,
                 sin_th: np.ndarray) -> tuple[list[Measurement], np.ndarray | None]:
    """The histogram filter's hook: the labeled readings (to go on as before) and the
    log-likelihood over the grid (nh, nx, ny) of the unlabeled ones, or None if there are
    none. Each unlabeled row's likelihood is a mixture over the beacons, uniform weights,
    plus clutter: ``p(z | x) = (1 - c) / n sum_b N_b(z | x) + c u`` with ``u`` uniform over
    bearings (and ranges up to ``max_range``) and ``c`` the sensor's clutter share
    (``rate / (1 + rate)``, at least ``MIN_CLUTTER_SHARE``). Each beacon's term is the
    filter's own von Mises bearing (noise inflated by the cell and the bin) and Gaussian range."""
    w = flt.__dict__.get("_association")
    if not isinstance(w, _GridWiring):
        w = flt._association = _GridWiring(flt.ctx)
    w.readings = []
    if not w.unknown:
        return list(measurements), None
    labeled: list[Measurement] = []
    total: np.ndarray | None = None
    cell_var = flt.cell ** 2 / 6.0
    nb = len(w.ids)
    for m in measurements:
        if not is_unlabeled(m):
            labeled.append(m)
            continue
        w.readings.append(m)
        spec = flt.ctx.sensor(m.sensor)
        std = spec.reading_std()
        c = max(spec.clutter_rate / (1.0 + spec.clutter_rate), MIN_CLUTTER_SHARE)
        rmax = spec.max_range if math.isfinite(spec.max_range) else math.hypot(flt.ctx.world.width,
                                                                              flt.ctx.world.height)
        log_u = -math.log(2.0 * math.pi) - (math.log(rmax) if m.kind == "range_bearing" else 0.0)
        base0 = math.log(c) + log_u           # the clutter term: the floor of the mixture
        share = math.log((1.0 - c) / nb)
        ranged = m.kind == "range_bearing"
        sr2 = std[0] ** 2 + cell_var if ranged else 1.0
        terms = [w.beacon_terms(flt, m.sensor, std, b) for b in range(nb)]
        for row in np.asarray(m.z, dtype=float):
            cz, sz = math.cos(row[-1]), math.sin(row[-1])
            # sum_b exp(term_b - base0), only where beacon b can explain the row (a range
            # within 6 sigma, a cell within max_range): the rest of each term is below
            # e^-18 of the floor and is left out.
            acc = np.zeros(flt.grid.shape)
            acc_flat = acc.reshape(flt.nh, -1)
            for b, (r, kappa_all, head_all, ca_all, sa_all) in enumerate(terms):
                if ranged:
                    lr = -0.5 * (r - row[0]) ** 2 / sr2
                    where = np.flatnonzero(lr > -18.0)
                else:
                    where = w.in_range(b, r, rmax + flt.cell)
                if where.size == 0:
                    continue
                kappa = kappa_all[where]
                ca, sa = ca_all[where], sa_all[where]
                # kappa (cos(z - alpha + theta) - 1) + log of the von Mises' normaliser
                core = w.scratch(flt.nh, where.size)
                np.multiply(cos_th[:, :, 0], (kappa * (cz * ca + sz * sa))[None], out=core)
                core -= sin_th[:, :, 0] * (kappa * (sz * ca - cz * sa))[None]
                base = head_all[where] + share - base0
                if ranged:
                    base = base + lr[where] - 0.5 * math.log(2.0 * math.pi * sr2)
                core += base[None]
                np.minimum(core, 700.0, out=core)
                np.exp(core, out=core)
                acc_flat[:, where] += core
            mix = base0 + np.log1p(acc)
            total = mix if total is None else total + mix
    return labeled, total
