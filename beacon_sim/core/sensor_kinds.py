"""The sensor kinds: one record each (core/sensor_kind.py), in :data:`KINDS`.

Every table of kinds the program reads is derived from these records when it is read (the
scenario's ``kind`` choices and keys, the simulation's draw, the readings' widths, the
tidy tables' columns, the filters' fallback to a kind's model, the Cramer-Rao bound), so
a kind registered later (``register_kind``, or ``KINDS[name] = record`` in a test) is
seen everywhere. Adding a kind = its record and model (here or in a module of its own)
and its tests (CONTRIBUTING.md, "Adding a sensor kind").

The built-in kinds' models weigh a reading at a particle filter's particles in fast forms
(``particle_fit``: core/particle_likelihood.py, the von Mises bearings and the fixes, which
the particle filter composes). The EKF, UKF and grid filter keep their own fast forms of
the built-in kinds (the readings on floats, the grid's separable terms); a kind they have no
form of is weighed with its record's model.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

import numpy as np

from beacon_sim.core import measurement_models as mm
from beacon_sim.core import particle_likelihood as pl
from beacon_sim.core.range_kind import RANGE
from beacon_sim.core.sensor_kind import KindParam, MeasurementModel, SensorKind
from beacon_sim.core.sensors import SensorSpec, sense, sense_scan
from beacon_sim.core.tdoa_fix_kind import TDOA_FIX
from beacon_sim.core.tdoa_kind import TDOA
from beacon_sim.core.types import Measurement
from beacon_sim.core.world import World

_I3 = np.eye(3)


class BearingModel(MeasurementModel):
    """``bearing``: h = atan2(yb - y, xb - x) - theta per beacon (seed 000)."""

    angles = (True,)

    def expected(self, spec: SensorSpec, m: Measurement, poses: np.ndarray, world: World) -> np.ndarray:
        return mm.bearing_many(poses, world.beacon_positions(m.beacon_ids))

    def jacobian(self, spec: SensorSpec, m: Measurement, pose: np.ndarray, world: World) -> np.ndarray:
        return mm.bearing_jacobian(pose, world.beacon_positions(m.beacon_ids))

    def noise(self, spec: SensorSpec, m: Measurement) -> np.ndarray:
        return np.diag(np.tile(spec.reading_std() ** 2, len(m)))

    def particle_constants(self, spec: SensorSpec) -> Any:
        return pl.beacon_constants(spec)

    def particle_fit(self, spec: SensorSpec, consts: Any, m: Measurement, cloud: pl.ParticleCloud,
                     world: World) -> pl.ParticleFit:
        return pl.von_mises_fit(spec, consts, m, cloud, world, False)


class RangeBearingModel(MeasurementModel):
    """``range_bearing``: ``[range, bearing]`` per beacon (seed 001)."""

    angles = (False, True)

    def expected(self, spec: SensorSpec, m: Measurement, poses: np.ndarray, world: World) -> np.ndarray:
        bxy = world.beacon_positions(m.beacon_ids)
        out = np.empty((poses.shape[0], 2 * bxy.shape[0]))
        out[:, 0::2] = mm.range_many(poses, bxy)
        out[:, 1::2] = mm.bearing_many(poses, bxy)
        return out

    def jacobian(self, spec: SensorSpec, m: Measurement, pose: np.ndarray, world: World) -> np.ndarray:
        return mm.range_bearing_jacobian(pose, world.beacon_positions(m.beacon_ids)).reshape(-1, 3)

    def noise(self, spec: SensorSpec, m: Measurement) -> np.ndarray:
        return np.diag(np.tile(spec.reading_std() ** 2, len(m)))

    def particle_constants(self, spec: SensorSpec) -> Any:
        return pl.beacon_constants(spec)

    def particle_fit(self, spec: SensorSpec, consts: Any, m: Measurement, cloud: pl.ParticleCloud,
                     world: World) -> pl.ParticleFit:
        return pl.von_mises_fit(spec, consts, m, cloud, world, True)


class PoseFixModel(MeasurementModel):
    """``pose``: h = pose, H = I (seed 003); noise shrinks with the beacons used."""

    angles = (False, False, True)

    def expected(self, spec: SensorSpec, m: Measurement, poses: np.ndarray, world: World) -> np.ndarray:
        return np.array(poses, dtype=float).reshape(-1, 3)

    def jacobian(self, spec: SensorSpec, m: Measurement, pose: np.ndarray, world: World) -> np.ndarray:
        return _I3.copy()

    def noise(self, spec: SensorSpec, m: Measurement) -> np.ndarray:
        return np.diag(spec.fix_std(max(len(m.beacon_ids), 1)) ** 2)

    def particle_fit(self, spec: SensorSpec, consts: Any, m: Measurement, cloud: pl.ParticleCloud,
                     world: World) -> pl.ParticleFit:
        return pl.pose_fit(spec, m, cloud, world)


class PositionFixModel(MeasurementModel):
    """``position``: h = (x, y), sigma = position_std * HDOP (seed 002)."""

    angles = (False, False)

    def expected(self, spec: SensorSpec, m: Measurement, poses: np.ndarray, world: World) -> np.ndarray:
        return np.array(np.asarray(poses, dtype=float).reshape(-1, 3)[:, :2])

    def jacobian(self, spec: SensorSpec, m: Measurement, pose: np.ndarray, world: World) -> np.ndarray:
        return mm.POSITION_H.copy()

    def noise(self, spec: SensorSpec, m: Measurement) -> np.ndarray:
        h = m.hdop if math.isfinite(m.hdop) else 1.0
        return np.diag(spec.fix_std(len(m.beacon_ids), h) ** 2)

    def particle_fit(self, spec: SensorSpec, consts: Any, m: Measurement, cloud: pl.ParticleCloud,
                     world: World) -> pl.ParticleFit:
        return pl.position_fit(spec, m, cloud, world)


def _sense_scan(spec: SensorSpec, pose: np.ndarray, world: World, rng: np.random.Generator) -> Measurement:
    return sense_scan(spec, pose, world, rng)


#: Every sensor kind by name: the built-in ones, then any registered.
KINDS: dict[str, SensorKind] = {k.name: k for k in (
    SensorKind("bearing", ("bearing_rad",), carries_ids=True, draw=sense, model=BearingModel(),
               label="bearings"),
    SensorKind("range_bearing", ("range_m", "bearing_rad"), carries_ids=True, draw=sense,
               model=RangeBearingModel(), label="range-bearing"),
    SensorKind("pose", ("x_m", "y_m", "theta_rad"), carries_ids=False, draw=sense, model=PoseFixModel(),
               label="pose fix"),
    SensorKind("position", ("x_m", "y_m"), carries_ids=False, draw=sense, model=PositionFixModel(),
               label="position fix"),
    # A laser scan (docs/maps.md): rows [range, beam angle]; read by the scan filters with
    # the beam model (no Gaussian model); its keys are read by core/scenario/parser.py.
    SensorKind("range_finder", ("range_m", "bearing_rad"), carries_ids=False, draw=_sense_scan,
               needs_beacons=False, needs_walls=True, label="laser scan", scan=True),
)}

#: The kinds with built-in scenario keys of their own (read by core/scenario/parser.py).
BUILTIN = tuple(KINDS)

# The distance kinds (docs/distance_beacons.md): each a record in a module of its own,
# registered as a plugin's kind would be.
KINDS.update({k.name: k for k in (RANGE, TDOA, TDOA_FIX)})


def register_kind(kind: SensorKind) -> SensorKind:
    """Add ``kind`` to :data:`KINDS` (a name already there is refused); returns it."""
    if kind.name in KINDS:
        raise ValueError(f"sensor kind {kind.name!r} is already registered")
    KINDS[kind.name] = kind
    return kind


def sensor_kind(name: str) -> SensorKind:
    """The record of kind ``name`` (ValueError naming the known kinds when there is none)."""
    try:
        return KINDS[name]
    except KeyError:
        raise ValueError(f"unknown sensor kind {name!r} (known: {', '.join(KINDS)})") from None


def kind_names() -> tuple[str, ...]:
    """The names of every registered kind, built-in first."""
    return tuple(KINDS)


def dims(name: str) -> int:
    """Width of one row of a reading of kind ``name``."""
    return sensor_kind(name).dims


def model_of(name: str) -> MeasurementModel | None:
    """The measurement model of kind ``name``; None for a kind without one or no such kind."""
    kind = KINDS.get(name)
    return None if kind is None else kind.model


def draw(spec: SensorSpec, pose: np.ndarray, world: World, rng: np.random.Generator) -> Measurement | None:
    """One reading of ``spec`` at the true ``pose`` (its kind's draw); None: nothing read."""
    return KINDS[spec.kind].draw(spec, pose, world, rng)


def beacon_kinds(names: Iterable[str] | None = None) -> tuple[str, ...]:
    """The kinds (of ``names``, default every one) whose rows name a beacon."""
    return tuple(n for n in (KINDS if names is None else names) if KINDS[n].carries_ids)


def names_beacons(name: str) -> bool:
    """Whether each row of a reading of kind ``name`` names its beacon (a kind not
    registered here, such as a team's robot sightings, is taken to)."""
    kind = KINDS.get(name)
    return True if kind is None else kind.carries_ids


def is_scan(name: str) -> bool:
    """Whether kind ``name`` is a laser scan (:attr:`SensorKind.scan`; a kind not registered
    here is not)."""
    kind = KINDS.get(name)
    return kind is not None and kind.scan


def scan_sensors(sensors: Iterable[SensorSpec]) -> tuple[str, ...]:
    """The names of the ``sensors`` whose kind is a laser scan, in order."""
    return tuple(s.name for s in sensors if is_scan(s.kind))


def table_rows(m: Measurement) -> tuple[np.ndarray, np.ndarray]:
    """The readings table's rows of ``m`` (its kind's :meth:`SensorKind.rows`): the beacon ID
    of each row (-1: none) and the rows of values; a kind not registered here names a beacon
    per row."""
    kind = KINDS.get(m.kind)
    if kind is None:
        return np.asarray(m.beacon_ids, dtype=int), np.asarray(m.z, dtype=float).reshape(len(m), -1)
    return kind.rows(m)


def param_keys() -> tuple[str, ...]:
    """The scenario keys every registered kind declares (``SensorKind.params``)."""
    return tuple(p.key for k in KINDS.values() for p in k.params)


def value_columns() -> tuple[str, ...]:
    """Every column name of every kind, each once, in the order the kinds declare them."""
    out: dict[str, None] = {}
    for k in KINDS.values():
        out.update(dict.fromkeys(k.columns))
    return tuple(out)


__all__ = ["BUILTIN", "KINDS", "BearingModel", "KindParam", "MeasurementModel", "PoseFixModel",
           "PositionFixModel", "RangeBearingModel", "SensorKind", "beacon_kinds", "dims", "draw",
           "is_scan", "kind_names", "model_of", "names_beacons", "param_keys", "register_kind",
           "scan_sensors", "sensor_kind", "table_rows", "value_columns"]
