"""Joint compatibility branch and bound (Neira and Tardos 2001): :func:`jcbb` for a pose
belief, and its search :func:`jcbb_search`, the one JCBB of the package (EKF-SLAM's full
state and FastSLAM's particles call it with their own :class:`JointTest`). A node cap
(:data:`MAX_NODES`) bounds a tick's search; past it, nearest neighbour."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Protocol

import numpy as np

from beacon_sim.filters.association.linearised import (
    GATE_PROB,
    Association,
    Linearised,
    Pairing,
    gate,
)
from beacon_sim.filters.association.nearest_neighbour import (
    check_ids,
    nn_pairing,
    to_association,
)

#: Default cap on the nodes JCBB may visit before it gives up and returns nearest neighbour.
#: A node costs about 10-40 us (one batched 3 x 3 solve for all its candidates; measured on a
#: loaded 2-core machine), so the cap bounds a tick's search at roughly 20-80 ms. Typical ticks
#: take tens of nodes; 15 readings + 3 clutter among 40 beacons with a 1 m position
#: uncertainty, ~850 (``benchmarks/bench_association.py``).
MAX_NODES = 2_000


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
    check_ids(lin, beacon_ids)
    pairing, _, nodes = jcbb_search(lin.d2, [lin.dim] * lin.nu.shape[0], JointInformation.of(lin),
                                    prob, max_nodes)
    if pairing is None:
        return to_association(lin, nn_pairing(lin, prob), beacon_ids, "nn-fallback", max_nodes)
    return to_association(lin, pairing, beacon_ids, "jcbb", nodes)
