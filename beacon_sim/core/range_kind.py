"""The ``range`` sensor kind: the distance to each beacon heard (two-way ranging, as UWB
tags do), optionally with positive non-line-of-sight (multipath) outliers.

One row per beacon heard, ``[range_m]``, naming its beacon. Beacons are
``beacon_height`` above the receiver (core/ceiling_beacons.py); a beacon is heard when it
is in range, field of view, line of sight (walls) and coverage cone and a draw with
``detection_prob`` succeeds. The reading is ``r + range_std e`` plus, with probability
``nlos_rate``, an exponential extra path of mean ``nlos_mean`` [m] (always longer: a
reflected path). The filters' model (:class:`RangeModel`): h = r, H = [(x - bx) / r,
(y - by) / r, 0], R = range_std^2 I; the log-likelihood on particles and grid cells is the
Gaussian, mixed with the exponential tail when the filter is told ``nlos_rate > 0``.
"""

from __future__ import annotations

import math

import numpy as np

from beacon_sim.core import ceiling_beacons as cb
from beacon_sim.core.sensor_kind import KindParam, MeasurementModel, SensorKind
from beacon_sim.core.sensors import SensorSpec
from beacon_sim.core.types import Measurement
from beacon_sim.core.world import World

NLOS_RATE = KindParam("nlos_rate", 0.0, 0.0, 0.5,
                      "probability that a range comes by a longer, reflected path")
NLOS_MEAN = KindParam("nlos_mean", 0.3, 1e-3, 100.0,
                      "mean extra length [m] of a reflected path (exponential)")


def draw_range(spec: SensorSpec, pose: np.ndarray, world: World,
               rng: np.random.Generator) -> Measurement | None:
    """Ranges [m] to the beacons heard at the true ``pose``; fixed-size draws (4 per
    beacon) and portable maths."""
    n = len(world.beacons)
    u_detect = rng.random(n)
    e = rng.standard_normal(n)
    u_nlos = rng.random(n)
    u_len = rng.random(n)
    heard = cb.covered_mask(spec, pose[None, :3], world)[0] & (u_detect < spec.detection_prob)
    idx = np.flatnonzero(heard)
    if idx.size < spec.min_beacons or idx.size == 0:
        return None
    r = cb.slant_ranges(np.asarray(pose, dtype=float)[None, :], world.beacon_xy[idx], spec.beacon_height)[0]
    z = r + spec.noise.range_std * e[idx]
    rate = spec.param("nlos_rate")
    if rate > 0.0:
        out = u_nlos[idx] < rate
        z[out] += cb.exponential(u_len[idx][out], spec.param("nlos_mean"))
    return Measurement(spec.name, "range", np.abs(z)[:, None], world.beacon_ids[idx])


class RangeModel(MeasurementModel):
    """``range``: h = slant range per beacon, R = range_std^2 I."""

    angles = (False,)

    def expected(self, spec: SensorSpec, m: Measurement, poses: np.ndarray, world: World) -> np.ndarray:
        return cb.slant_ranges(np.asarray(poses, dtype=float).reshape(-1, 3),
                               world.beacon_positions(m.beacon_ids), spec.beacon_height)

    def jacobian(self, spec: SensorSpec, m: Measurement, pose: np.ndarray, world: World) -> np.ndarray:
        return cb.range_jacobian(pose, world.beacon_positions(m.beacon_ids), spec.beacon_height)

    def noise(self, spec: SensorSpec, m: Measurement) -> np.ndarray:
        return np.eye(len(m)) * spec.noise.range_std ** 2

    def loglik(self, spec: SensorSpec, m: Measurement, poses: np.ndarray, world: World) -> np.ndarray:
        """Per row: Gaussian; told ``nlos_rate`` = q > 0, the mixture
        ``(1 - q) N(nu; 0, s^2) + q Exp(nu; nlos_mean)`` (nu > 0), constant dropped."""
        rate = spec.param("nlos_rate")
        nu = self.residual(m, self.expected(spec, m, poses, world))   # (N, k)
        s = spec.noise.range_std
        g = -0.5 * (nu / s) ** 2
        if rate <= 0.0:
            return g.sum(axis=1)
        lam = spec.param("nlos_mean")
        log_g = math.log1p(-rate) - math.log(s * math.sqrt(2.0 * math.pi)) + g
        log_e = np.where(nu > 0.0, math.log(rate / lam) - nu / lam, -np.inf)
        return np.logaddexp(log_g, log_e).sum(axis=1)

    def information(self, spec: SensorSpec, poses: np.ndarray, world: World) -> np.ndarray:
        """``p H^T H / s^2`` over the beacons heard, p = detection_prob (1 - nlos_rate) (the
        outliers' information approximated by none)."""
        poses = np.asarray(poses, dtype=float).reshape(-1, 3)
        p = spec.detection_prob * (1.0 - spec.param("nlos_rate")) / spec.noise.range_std ** 2
        vis = cb.covered_mask(spec, poses, world)
        d = poses[:, None, :2] - world.beacon_xy[None]
        r = np.sqrt(np.sum(d * d, axis=2) + spec.beacon_height ** 2)
        g = vis[..., None] * d / np.maximum(r, 1e-12)[..., None]      # (N, n, 2)
        out = np.zeros((poses.shape[0], 3, 3))
        out[:, :2, :2] = p * np.einsum("rbi,rbj->rij", g, g)
        return out


def check_range(spec: SensorSpec, world: World, path: str) -> str | None:
    """One beacon at least, none two at one point, and no uniform outliers (``nlos_rate``
    is this kind's)."""
    if spec.outlier_rate > 0.0:
        return (f"{path}.outlier_rate = {spec.outlier_rate:g}: expected 0 for a range sensor "
                f"(its outliers are nlos_rate, longer paths)")
    return cb.check_layout(spec, world, 1)


RANGE = SensorKind("range", ("range_m",), carries_ids=True, draw=draw_range, model=RangeModel(),
                   params=(NLOS_RATE, NLOS_MEAN, cb.CONE), label="ranges", check=check_range)

__all__ = ["NLOS_MEAN", "NLOS_RATE", "RANGE", "RangeModel", "check_range", "draw_range"]
