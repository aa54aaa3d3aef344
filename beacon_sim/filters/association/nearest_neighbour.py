"""Greedy nearest neighbour inside the gate (:func:`nearest_neighbour`), and the pairing
turned into an :class:`~beacon_sim.filters.association.linearised.Association`
(:func:`to_association`), which JCBB shares."""

from __future__ import annotations

import numpy as np

from beacon_sim.filters.association.linearised import (
    GATE_PROB,
    Association,
    Linearised,
    Pairing,
    gate,
    joint_nis,
)


def check_ids(lin: Linearised, beacon_ids: np.ndarray) -> None:
    if len(beacon_ids) != lin.H.shape[0]:
        raise ValueError(f"association: {len(beacon_ids)} beacon IDs for {lin.H.shape[0]} beacons")


def to_association(lin: Linearised, pairing: Pairing, beacon_ids: np.ndarray, method: str,
                 nodes: int = 0) -> Association:
    ids: list[int | None] = [None] * lin.nu.shape[0]
    for i, j in pairing:
        ids[i] = int(beacon_ids[j])
    return Association(tuple(ids), method, joint_nis(lin, pairing), lin.dim * len(pairing), nodes)


def nn_pairing(lin: Linearised, prob: float) -> Pairing:
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
    check_ids(lin, beacon_ids)
    return to_association(lin, nn_pairing(lin, prob), beacon_ids, "nn")
