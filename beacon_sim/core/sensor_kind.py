"""What a sensor kind is: a record (:class:`SensorKind`) and its measurement model
(:class:`MeasurementModel`, the likelihood / linearisation policy every filter shares).

A kind says how wide one row of its readings is and what each column means (name with
unit: the table and export columns), whether each row names a beacon, which scenario keys
it adds to a ``[[sensors]]`` table, how the simulation draws a reading, and how a reading
is weighed: ``h`` (expected reading at poses), ``H`` (its Jacobian), ``R`` (its noise
covariance, a full matrix: correlated rows are allowed) and the log-likelihood at many poses
(particles, grid cells). The Gaussian filters use h, H and R, the particle and grid filters
the log-likelihood (a particle filter through :meth:`MeasurementModel.particle_fit`, on its
own buffers: core/particle_likelihood.py), the Cramer-Rao bound the Fisher information. The
registry of kinds is core/sensor_kinds.py.

Frames and units: poses ``[x, y, theta]`` [m, m, rad] in the world frame; angle components
of a reading are wrapped to [-pi, pi) and their residuals are wrapped before use.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.particle_likelihood import ParticleCloud, ParticleFit
from beacon_sim.core.sensors import SensorSpec, visible_mask
from beacon_sim.core.types import Measurement
from beacon_sim.core.world import World

#: How the simulation draws one reading of a sensor at the true pose (its stream ``rng``);
#: None when nothing was measured. Everything it computes must use core/portable_math.py
#: (or ``portable=True`` in core/measurement_models.py): the same bits on every machine.
Draw = Callable[[SensorSpec, np.ndarray, World, np.random.Generator], "Measurement | None"]

#: Why a sensor of this kind cannot work in a world (None: it can), checked when a scenario
#: is loaded; given the sensor, the world and the sensor table's path (``sensors[0]``), it
#: returns ``"key = value: expected ..."`` with the key's full path (the loader adds the file).
Check = Callable[[SensorSpec, World, str], "str | None"]

#: The readings table's rows of one reading (exports, MCAP, Foxglove): the beacon ID of each
#: row (-1: none) and the rows of values (k', d).
TableRows = Callable[[Measurement], "tuple[np.ndarray, np.ndarray]"]


@dataclass(frozen=True)
class KindParam:
    """A scenario key a kind adds to its ``[[sensors]]`` table: a number in ``[lo, hi]``
    (``default`` when absent), read into ``SensorSpec.params``."""

    key: str
    default: float
    lo: float
    hi: float
    meaning: str = ""


class MeasurementModel:
    """The likelihood / linearisation policy of one kind (subclass it; a kind's record holds
    one instance). Shapes for one reading ``m`` of k rows and d columns: ``z`` flattened row
    by row is ``k d`` numbers.

    Subclasses write :meth:`expected`, :meth:`jacobian` and :meth:`noise`; the
    log-likelihood and the Fisher information follow from them (override them for speed or
    for a non-Gaussian model).
    """

    #: Which of the d columns of a row are angles (their residuals are wrapped).
    angles: tuple[bool, ...] = ()

    def expected(self, spec: SensorSpec, m: Measurement, poses: np.ndarray, world: World) -> np.ndarray:
        """h at poses (N, 3): the expected readings (N, k d), angle columns wrapped."""
        raise NotImplementedError

    def jacobian(self, spec: SensorSpec, m: Measurement, pose: np.ndarray, world: World) -> np.ndarray:
        """H = dh/dpose at one pose (3,): shape (k d, 3)."""
        raise NotImplementedError

    def noise(self, spec: SensorSpec, m: Measurement) -> np.ndarray:
        """R, the noise covariance of the flattened reading: shape (k d, k d)."""
        raise NotImplementedError

    def noise_at(self, spec: SensorSpec, m: Measurement, world: World) -> np.ndarray:
        """R where it depends on the map too (a fix's covariance from the beacons'
        geometry); by default :meth:`noise`. The filters and :meth:`loglik` call this one."""
        return self.noise(spec, m)

    def angle_rows(self, m: Measurement) -> np.ndarray:
        """(k d,) bool: the flattened rows that are angles."""
        return np.tile(np.asarray(self.angles, dtype=bool), len(m))

    def residual(self, m: Measurement, h: np.ndarray) -> np.ndarray:
        """``z - h`` (..., k d) with angle rows wrapped."""
        nu = np.asarray(m.z, dtype=float).reshape(-1) - h
        ang = self.angle_rows(m)
        if ang.any():
            nu[..., ang] = wrap(nu[..., ang])
        return nu

    def linearise(self, spec: SensorSpec, m: Measurement, pose: np.ndarray, world: World
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(H (k d, 3), nu = z - h(pose) (k d,), R (k d, k d))`` at one pose: the EKF's."""
        pose = np.asarray(pose, dtype=float).reshape(3)
        h = self.expected(spec, m, pose[None, :], world)[0]
        return self.jacobian(spec, m, pose, world), self.residual(m, h), self.noise_at(spec, m, world)

    def loglik(self, spec: SensorSpec, m: Measurement, poses: np.ndarray, world: World) -> np.ndarray:
        """Log-likelihood of ``m`` at poses (N, 3), up to a constant that is the same at every
        pose: ``-0.5 nu^T R^-1 nu`` (N,), on arrays (no loop over poses)."""
        nu = self.residual(m, self.expected(spec, m, np.asarray(poses, dtype=float).reshape(-1, 3), world))
        L = np.linalg.cholesky(self.noise_at(spec, m, world))
        w = np.linalg.solve(L, nu.T)          # (k d, N): whitened residuals
        return -0.5 * np.einsum("ij,ij->j", w, w)

    def particle_constants(self, spec: SensorSpec) -> Any:
        """What :meth:`particle_fit` needs of a sensor that does not change (its noise),
        worked out once per sensor by the filter that keeps it; None by default."""
        return None

    def particle_fit(self, spec: SensorSpec, consts: Any, m: Measurement, cloud: ParticleCloud,
                     world: World) -> ParticleFit:
        """``m`` weighed at a particle filter's particles (core/particle_likelihood.py);
        ``consts`` is :meth:`particle_constants`. By default :meth:`loglik` on the particles
        as float64 poses, one fit for the whole reading, not mixed with outliers; the
        built-in kinds have fast forms on the particles' own dtype and buffers."""
        size = int(m.z.size)
        return ParticleFit(self.loglik(spec, m, cloud.poses64(), world), size, size)

    def information(self, spec: SensorSpec, poses: np.ndarray, world: World) -> np.ndarray:
        """Expected Fisher information (R, 3, 3) of one reading at true poses (R, 3):
        ``p H^T R^-1 H`` of the reading the pose would give, p = detection probability
        times (1 - outlier rate). A kind whose rows name beacons reads every beacon in
        view (range, field of view, walls); any other kind one row."""
        poses = np.asarray(poses, dtype=float).reshape(-1, 3)
        p = spec.detection_prob * (1.0 - spec.outlier_rate)
        d = len(self.angles)
        out = np.zeros((poses.shape[0], 3, 3))
        vis = visible_mask(spec, poses, world) if world.beacons else None
        for i, pose in enumerate(poses):
            if vis is not None and self.carries_ids:
                ids = world.beacon_ids[vis[i]]
                if not ids.size:
                    continue
            else:
                ids = np.zeros(0, dtype=int)
            k = max(ids.size, 1)
            m = Measurement(spec.name, "", np.zeros((k, d)), ids)
            H = self.jacobian(spec, m, pose, world)
            out[i] = p * H.T @ np.linalg.solve(self.noise(spec, m), H)
        return out

    #: Whether each row names a beacon (set from the record when it is registered).
    carries_ids: bool = True


@dataclass(frozen=True)
class SensorKind:
    """One sensor kind.

    Attributes
    ----------
    name : str
        The name a scenario's ``kind = "..."`` uses.
    columns : tuple of str
        One row of ``Measurement.z``: each column's name with its unit (``range_m``,
        ``bearing_rad``): the tidy tables' and exports' column names. d = len(columns).
    carries_ids : bool
        Each row names the beacon it was read from (``Measurement.beacon_ids``, one per row);
        False: the IDs, if any, are not per row (a fix's beacons, a scan's none).
    draw : callable
        The simulation's reading (:data:`Draw`).
    model : MeasurementModel or None
        The likelihood / linearisation policy; None: no Gaussian model (a laser scan, read
        by the scan filters with their beam model).
    params : tuple of KindParam
        The scenario keys the kind adds (read into ``SensorSpec.params``).
    needs_beacons, needs_walls : bool
        A scenario with a sensor of this kind must have beacons / walls.
    label : str
        What the window's panel calls it.
    check : callable or None
        Why a sensor of this kind cannot work in a world (:data:`Check`), asked when a
        scenario is loaded; None: nothing to check beyond the keys' ranges.
    table_rows : callable or None
        The readings table's rows of a reading (:data:`TableRows`); None: z's rows, each
        with its beacon when ``carries_ids`` (else -1).
    scan : bool
        A laser scan: each row is one beam ``[range_m, bearing_rad]`` in the robot frame;
        the scenario reads its beams (``n_beams``, ``fov``) and beam model keys and wants a
        finite ``max_range``; the scan filters (mcl, corridor) read it, the Gaussian filters
        have no slots for it; its Cramer-Rao information comes from the walls
        (core/scan_jacobian.py); it is drawn as a LaserScan in the exports.
    """

    name: str
    columns: tuple[str, ...]
    carries_ids: bool
    draw: Draw
    model: MeasurementModel | None = None
    params: tuple[KindParam, ...] = ()
    needs_beacons: bool = True
    needs_walls: bool = False
    label: str = ""
    check: Check | None = None
    table_rows: TableRows | None = None
    scan: bool = False

    def __post_init__(self) -> None:
        if self.model is not None:
            if len(self.model.angles) != len(self.columns):
                raise ValueError(f"sensor kind {self.name!r}: its model has {len(self.model.angles)} "
                                 f"columns, its record {len(self.columns)}")
            self.model.carries_ids = self.carries_ids

    def rows(self, m: Measurement) -> tuple[np.ndarray, np.ndarray]:
        """(beacon ID per row (-1: none), rows of values) of ``m`` for the readings table."""
        if self.table_rows is not None:
            return self.table_rows(m)
        z = np.asarray(m.z, dtype=float).reshape(len(m), -1)
        ids = np.asarray(m.beacon_ids, dtype=int) if self.carries_ids else np.full(len(m), -1)
        return ids, z

    @property
    def dims(self) -> int:
        """Width d of one row of ``Measurement.z``."""
        return len(self.columns)

    @property
    def angles(self) -> tuple[bool, ...]:
        """Which columns are angles (``*_rad``)."""
        return tuple(c.endswith("_rad") for c in self.columns)


__all__ = ["Check", "Draw", "KindParam", "MeasurementModel", "SensorKind", "TableRows"]
