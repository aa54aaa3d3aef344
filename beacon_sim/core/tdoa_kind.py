"""The ``tdoa`` sensor kind: range differences against a reference beacon (time differences
of arrival times the speed of sound), as seed 002's ultrasonic beacons give them.

The beacons emit together; the receiver times each arrival, ``t_i = r_i + s e_i`` [m] (s =
``range_std``, seed 002's sigma_d), and, sharing no clock with the beacons, keeps only the
differences against a reference beacon: ``d_i = t_i - t_ref`` for every other beacon heard.
All of them carry the reference's error, so their covariance is ``s^2 (I + 1 1^T)``
(variance 2 s^2 each, covariance s^2 between any two): the true R of :class:`TdoaModel`.
Told ``naive_differences = 1`` a filter takes them as independent with variance 2 s^2 each,
as common firmware does (the wrong shape of ellipse: docs/distance_beacons.md).

A reading: ``z`` (k, 1), row i the difference ``d_i`` [m]; ``beacon_ids`` (k + 1,) the
reference first, then the beacon of each row (the rows do not each name their beacon
alone, so the record's ``carries_ids`` is False). The reference is ``reference_id`` (a
tick on which it is not heard gives no reading) or, with ``reference_id = -1``, the
strongest beacon heard (the nearest). In the readings table (exports) the reference is a row
of its own, difference 0, so every row names its beacon. Geometry, cone and walls:
core/ceiling_beacons.py.
"""

from __future__ import annotations

import math

import numpy as np

from beacon_sim.core import ceiling_beacons as cb
from beacon_sim.core.sensor_kind import KindParam, MeasurementModel, SensorKind
from beacon_sim.core.sensors import SensorSpec
from beacon_sim.core.types import Measurement
from beacon_sim.core.world import World

REFERENCE = KindParam("reference_id", -1.0, -1.0, 2.0**31 - 1,
                      "ID of the reference beacon (-1: the strongest heard on each reading)")
NAIVE = KindParam("naive_differences", 0.0, 0.0, 1.0,
                  "1: the filters take the differences as independent, 2 s^2 each (wrong); "
                  "0: their true covariance s^2 (I + 1 1^T)")

#: Detection subsets are enumerated for the bound up to this many beacons (else approximated).
MAX_SUBSET_BEACONS = 12


def least_heard(spec: SensorSpec) -> int:
    """Beacons a reading needs: two (one difference), or ``min_beacons`` if more."""
    return max(2, spec.min_beacons)


def naive(spec: SensorSpec) -> bool:
    """Whether the filters told ``spec`` take the differences as independent."""
    return spec.param("naive_differences") >= 0.5


def choose_reference(spec: SensorSpec, idx: np.ndarray, r: np.ndarray, world: World) -> int | None:
    """Index (into ``idx``) of the reference among the beacons heard ``idx`` at true ranges
    ``r``: the scenario's, or the nearest (first of equals); None when the scenario's
    reference is not heard."""
    ref_id = int(spec.param("reference_id"))
    if ref_id < 0:
        return int(np.argmin(r))
    hit = np.flatnonzero(world.beacon_ids[idx] == ref_id)
    return int(hit[0]) if hit.size else None


def draw_tdoa(spec: SensorSpec, pose: np.ndarray, world: World,
              rng: np.random.Generator) -> Measurement | None:
    """Range differences [m] against the reference at the true ``pose``; fixed-size draws
    (2 per beacon), portable maths."""
    n = len(world.beacons)
    u_detect = rng.random(n)
    e = rng.standard_normal(n)
    heard = cb.covered_mask(spec, pose[None, :3], world)[0] & (u_detect < spec.detection_prob)
    idx = np.flatnonzero(heard)
    if idx.size < least_heard(spec):
        return None
    r = cb.slant_ranges(np.asarray(pose, dtype=float)[None, :], world.beacon_xy[idx], spec.beacon_height)[0]
    ref = choose_reference(spec, idx, r, world)
    if ref is None:
        return None
    t = r + spec.noise.range_std * e[idx]          # arrival [m]: range plus timing noise
    others = np.delete(np.arange(idx.size), ref)
    z = (t[others] - t[ref])[:, None]
    ids = np.concatenate([world.beacon_ids[idx[ref:ref + 1]], world.beacon_ids[idx[others]]])
    return Measurement(spec.name, "tdoa", z, ids)


def difference_cov(k: int, s: float, independent: bool = False) -> np.ndarray:
    """Covariance (k, k) [m^2] of k differences against one reference, each arrival of
    standard deviation s: ``s^2 (I + 1 1^T)``; ``independent``: ``2 s^2 I`` (the naive one)."""
    if independent:
        return np.eye(k) * (2.0 * s * s)
    return s * s * (np.eye(k) + np.ones((k, k)))


class TdoaModel(MeasurementModel):
    """``tdoa``: h_i = r_i - r_ref, H_i = dr_i/dpose - dr_ref/dpose, R = s^2 (I + 1 1^T)
    (told ``naive_differences``: 2 s^2 I)."""

    angles = (False,)

    def expected(self, spec: SensorSpec, m: Measurement, poses: np.ndarray, world: World) -> np.ndarray:
        r = cb.slant_ranges(np.asarray(poses, dtype=float).reshape(-1, 3),
                            world.beacon_positions(m.beacon_ids), spec.beacon_height)
        return r[:, 1:] - r[:, :1]

    def jacobian(self, spec: SensorSpec, m: Measurement, pose: np.ndarray, world: World) -> np.ndarray:
        J = cb.range_jacobian(pose, world.beacon_positions(m.beacon_ids), spec.beacon_height)
        return J[1:] - J[:1]

    def noise(self, spec: SensorSpec, m: Measurement) -> np.ndarray:
        return difference_cov(len(m), spec.noise.range_std, naive(spec))

    def information(self, spec: SensorSpec, poses: np.ndarray, world: World) -> np.ndarray:
        """Expected Fisher information (N, 3, 3) of one reading with the true covariance:
        for the set G of unit vectors (rows ``(p - b) / r``, x-y part) of the beacons heard,
        ``G^T (I - 1 1^T / n) G / s^2``, whichever the reference (the differences carry all
        the ranges' information but their common part); averaged over which beacons are
        detected (enumerated up to :data:`MAX_SUBSET_BEACONS` beacons)."""
        poses = np.asarray(poses, dtype=float).reshape(-1, 3)
        N, nb = poses.shape[0], len(world.beacons)
        vis = cb.covered_mask(spec, poses, world)
        d = poses[:, None, :2] - world.beacon_xy[None]
        r = np.sqrt(np.sum(d * d, axis=2) + spec.beacon_height ** 2)
        g = d / np.maximum(r, 1e-12)[..., None]                      # (N, nb, 2)
        ref_id = int(spec.param("reference_id"))
        ref_col = None if ref_id < 0 else int(world.beacon_index([ref_id])[0])
        need = least_heard(spec)
        p = spec.detection_prob
        out = np.zeros((N, 3, 3))
        if p >= 1.0 or nb > MAX_SUBSET_BEACONS:
            masks, weights = [vis], [np.full(N, 1.0 if p >= 1.0 else p)]
        else:
            masks, weights = [], []
            for bits in range(1, 2 ** nb):
                sub = np.array([(bits >> j) & 1 for j in range(nb)], dtype=bool)
                inside = np.all(vis[:, sub], axis=1)
                n_vis = vis.sum(axis=1)
                k = int(sub.sum())
                w = np.where(inside, p ** k * (1.0 - p) ** (n_vis - k), 0.0)
                masks.append(vis & sub[None, :])
                weights.append(w)
        for mask, w in zip(masks, weights, strict=True):
            n = mask.sum(axis=1)
            ok = (n >= need) & (w > 0)
            if ref_col is not None:
                ok &= mask[:, ref_col]
            gm = g * mask[..., None]
            s1 = gm.sum(axis=1)                                      # (N, 2)
            S2 = np.einsum("rbi,rbj->rij", gm, gm)
            info = S2 - np.einsum("ri,rj->rij", s1, s1) / np.maximum(n, 1)[:, None, None]
            out[:, :2, :2] += (ok * w)[:, None, None] * info
        return out / spec.noise.range_std ** 2


def tdoa_table_rows(m: Measurement) -> tuple[np.ndarray, np.ndarray]:
    """The readings table's rows of a tdoa reading: the reference first, its difference
    against itself exactly 0, then each beacon's difference, every row naming its beacon."""
    z = np.vstack([np.zeros((1, 1)), np.asarray(m.z, dtype=float).reshape(-1, 1)])
    return np.asarray(m.beacon_ids, dtype=int), z


def check_tdoa(spec: SensorSpec, world: World, path: str) -> str | None:
    """Two beacons at least, none two at one point, a reference that is a beacon the
    receiver can hear somewhere in the world, no uniform outliers."""
    if spec.outlier_rate > 0.0:
        return f"{path}.outlier_rate = {spec.outlier_rate:g}: expected 0 for a tdoa sensor"
    why = cb.check_layout(spec, world, 2)
    if why:
        return why
    ref = spec.param("reference_id")
    if ref >= 0:
        if ref != math.floor(ref) or int(ref) not in set(world.beacon_ids.tolist()):
            return (f"{path}.reference_id = {ref:g}: expected -1 (the strongest) or the ID of "
                    f"one of the world's beacons ({', '.join(map(str, world.beacon_ids.tolist()))})")
        b = world.beacon_positions([int(ref)])[0]
        xmin, ymin, xmax, ymax = world.bounds
        gap = math.hypot(max(xmin - b[0], 0.0, b[0] - xmax), max(ymin - b[1], 0.0, b[1] - ymax))
        a = spec.param("cone_half_angle")
        cone = math.inf if a >= 0.5 * math.pi else spec.beacon_height * math.tan(a)
        if gap > min(spec.max_range, cone):
            return (f"{path}.reference_id = {int(ref)}: expected a beacon the receiver can hear "
                    f"somewhere in world.bounds (it is {gap:.3g} m outside them, heard within "
                    f"{min(spec.max_range, cone):.3g} m)")
    nd = spec.param("naive_differences")
    if nd not in (0.0, 1.0):
        return f"{path}.naive_differences = {nd:g}: expected 0 or 1"
    return None


TDOA = SensorKind("tdoa", ("range_diff_m",), carries_ids=False, draw=draw_tdoa, model=TdoaModel(),
                  params=(REFERENCE, NAIVE, cb.CONE), label="range differences", check=check_tdoa,
                  table_rows=tdoa_table_rows)

__all__ = ["MAX_SUBSET_BEACONS", "NAIVE", "REFERENCE", "TDOA", "TdoaModel", "check_tdoa",
           "choose_reference", "difference_cov", "draw_tdoa", "least_heard", "naive", "tdoa_table_rows"]
