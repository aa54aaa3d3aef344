"""The ``tdoa_fix`` sensor kind: the loose coupling of seed 002. The receiver takes the
range differences of a ``tdoa`` sensor (core/tdoa_kind.py, drawn the same way from the
same stream) and trilaterates them itself (core/trilateration.py, Gauss-Newton); the
filters get the position fix and its covariance from the geometry, as any position fix.

A reading: ``z`` (1, 2) the fix ``[x, y]`` [m]; ``beacon_ids`` the beacons used, the
reference first; ``hdop`` the fix's HDOP (``sqrt(trace(cov)) / range_std``). A tick whose
differences give no fix (fewer than three beacons heard, an ambiguous or degenerate
geometry) gives no reading. The filters' R (:class:`TdoaFixModel`): the geometry's
covariance ``s^2 (D^T C^-1 D)^-1`` at the fix (the HDOP ellipse), or, told
``isotropic_fix = 1``, seed 002's eq. 11: ``(s HDOP)^2`` on each axis.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from beacon_sim.core import ceiling_beacons as cb
from beacon_sim.core.sensor_kind import KindParam, MeasurementModel, SensorKind
from beacon_sim.core.sensors import SensorSpec
from beacon_sim.core.tdoa_kind import REFERENCE, TdoaModel, check_tdoa, draw_tdoa
from beacon_sim.core.trilateration import TrilaterationError, fix_covariance, trilaterate
from beacon_sim.core.types import Measurement
from beacon_sim.core.world import World

ISOTROPIC = KindParam("isotropic_fix", 0.0, 0.0, 1.0,
                      "1: the filters take the fix's noise as (range_std HDOP)^2 on each axis "
                      "(seed 002's eq. 11); 0: the geometry's full covariance")

_H = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def _tdoa_spec(spec: SensorSpec) -> SensorSpec:
    """The spec as a ``tdoa`` sensor would have it (its keys; three beacons at least)."""
    keep = {k: v for k, v in spec.params if k in ("reference_id", "cone_half_angle")}
    return replace(spec, min_beacons=max(3, spec.min_beacons),
                   params=(("reference_id", keep["reference_id"]), ("naive_differences", 0.0),
                           ("cone_half_angle", keep["cone_half_angle"])))


def draw_tdoa_fix(spec: SensorSpec, pose: np.ndarray, world: World,
                  rng: np.random.Generator) -> Measurement | None:
    """The differences of a tdoa sensor (the same draws), trilaterated."""
    m = draw_tdoa(_tdoa_spec(spec), pose, world, rng)
    if m is None:
        return None
    bxy = world.beacon_positions(m.beacon_ids)
    try:
        fix = trilaterate(m.z[:, 0], bxy[0], bxy[1:], spec.beacon_height, spec.noise.range_std)
    except TrilaterationError:
        return None
    return Measurement(spec.name, "tdoa_fix", fix.xy[None, :], m.beacon_ids, hdop=fix.hdop)


class TdoaFixModel(MeasurementModel):
    """``tdoa_fix``: h = (x, y), H = [I 0], R = the fix's covariance from the geometry."""

    angles = (False, False)

    def expected(self, spec: SensorSpec, m: Measurement, poses: np.ndarray, world: World) -> np.ndarray:
        return np.array(np.asarray(poses, dtype=float).reshape(-1, 3)[:, :2])

    def jacobian(self, spec: SensorSpec, m: Measurement, pose: np.ndarray, world: World) -> np.ndarray:
        return _H.copy()

    def noise(self, spec: SensorSpec, m: Measurement) -> np.ndarray:
        """Without the map: ``(s HDOP)^2`` on each axis (seed 002's eq. 11)."""
        h = m.hdop if np.isfinite(m.hdop) else 1.0
        return np.eye(2) * (spec.noise.range_std * h) ** 2

    def noise_at(self, spec: SensorSpec, m: Measurement, world: World) -> np.ndarray:
        if spec.param("isotropic_fix") >= 0.5:
            return self.noise(spec, m)
        bxy = world.beacon_positions(m.beacon_ids)
        try:
            return fix_covariance(np.asarray(m.z, dtype=float)[0], bxy[0], bxy[1:], spec.beacon_height,
                                  spec.noise.range_std)
        except TrilaterationError:
            return self.noise(spec, m)

    def information(self, spec: SensorSpec, poses: np.ndarray, world: World) -> np.ndarray:
        """The differences' information (the fix carries it, to first order), when three
        beacons or more are heard."""
        return TdoaModel().information(_tdoa_spec(spec), poses, world)


def check_tdoa_fix(spec: SensorSpec, world: World, path: str) -> str | None:
    """As a tdoa sensor's, and three beacons at least (two differences fix x and y)."""
    why = check_tdoa(_tdoa_spec(spec), world, path)
    if why is None and len(world.beacons) < 3:
        return (f"world.beacons: {len(world.beacons)} beacon(s): expected at least 3 for a "
                f"tdoa_fix sensor (two differences fix x and y)")
    if why is None and spec.param("isotropic_fix") not in (0.0, 1.0):
        return f"{path}.isotropic_fix = {spec.param('isotropic_fix'):g}: expected 0 or 1"
    return why


TDOA_FIX = SensorKind("tdoa_fix", ("x_m", "y_m"), carries_ids=False, draw=draw_tdoa_fix,
                      model=TdoaFixModel(), params=(REFERENCE, ISOTROPIC, cb.CONE),
                      label="trilaterated fix", check=check_tdoa_fix)

__all__ = ["ISOTROPIC", "TDOA_FIX", "TdoaFixModel", "check_tdoa_fix", "draw_tdoa_fix"]
