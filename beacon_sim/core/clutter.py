"""The sensor side of unknown correspondence: readings without IDs, clutter, look-alike maps.

A pure step after :func:`beacon_sim.core.sensors.sense`: ``(measurement, spec, rng) ->
measurement``. It adds false detections (clutter) and hides which beacon each row came from,
keeping the truth aside for metrics. The simulation calls :func:`unlabel` for every sensor
whose scenario table says ``correspondence = "unknown"`` (its ``clutter_rate`` the Poisson
mean), on a stream of its own (``stream(seed, "clutter", sensor)``), and puts the true IDs in
``Step.true_ids``, never in what the filters receive.

- Clutter: a Poisson number of false readings per reading tick (mean ``rate``), range
  uniform in [0, max_range] [m] and bearing uniform over the field of view [rad], relative to
  the robot's heading like every reading.
- Hidden IDs: every row's ``beacon_ids`` entry becomes :data:`UNKNOWN_ID` and the rows are
  shuffled (otherwise their order, the map's order, would give the IDs away).
- Randomness: only from the ``rng`` passed in. How many numbers are drawn depends on the
  Poisson count, so give this step a generator of its own (spawned from the run's
  ``SeedSequence``): then it never shifts another stream, and a seed gives the same run.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from beacon_sim.core import portable_math as pm
from beacon_sim.core.angles import wrap
from beacon_sim.core.sensors import SensorSpec
from beacon_sim.core.types import Beacon, Measurement

#: The ``beacon_ids`` entry of a reading whose beacon is not told (and of clutter's truth).
UNKNOWN_ID = -1

#: The kinds that carry per-beacon readings (fixes pass through unchanged).
READING_KINDS = ("bearing", "range_bearing")


@dataclass(frozen=True)
class ClutterSpec:
    """False detections of one beacon sensor.

    Attributes
    ----------
    rate : float
        Mean number of false readings per reading tick (Poisson), >= 0.
    max_range : float
        Clutter ranges are uniform in [0, max_range] [m]; ``inf`` (the default) takes the
        sensor's ``max_range``, which must then be finite.
    """

    rate: float = 0.0
    max_range: float = math.inf

    def __post_init__(self) -> None:
        if not (math.isfinite(self.rate) and self.rate >= 0.0):
            raise ValueError(f"clutter rate must be a finite number >= 0, got {self.rate!r}")
        if not self.max_range > 0.0:
            raise ValueError(f"clutter max_range must be > 0 [m], got {self.max_range!r}")

    def range_limit(self, sensor: SensorSpec) -> float:
        """The largest clutter range [m] for ``sensor``."""
        limit = self.max_range if math.isfinite(self.max_range) else sensor.max_range
        if not math.isfinite(limit):
            raise ValueError(f"sensor {sensor.name!r}: clutter needs a finite max_range "
                             "(the sensor's or the clutter's own)")
        return float(limit)


@dataclass(frozen=True, eq=False)
class Unlabeled:
    """A reading with its IDs hidden, and the truth kept for scoring.

    Attributes
    ----------
    measurement : Measurement
        What a filter sees: rows shuffled, every ``beacon_ids`` entry :data:`UNKNOWN_ID`.
    true_ids : ndarray of int, shape (m,)
        The beacon each row really came from; :data:`UNKNOWN_ID` for clutter.
    """

    measurement: Measurement
    true_ids: np.ndarray


def draw_clutter(sensor: SensorSpec, clutter: ClutterSpec, rng: np.random.Generator) -> np.ndarray:
    """False readings of one tick, shape (k, d) with k ~ Poisson(rate): ``[b]`` or ``[r, b]``.

    Bearings are uniform over the field of view centred on the heading (all around for
    ``fov >= 2 pi``), ranges uniform in ``[0, clutter.range_limit(sensor)]``.
    """
    if sensor.kind not in READING_KINDS:
        raise ValueError(f"clutter is for beacon sensors, not {sensor.kind!r}")
    k = int(rng.poisson(clutter.rate)) if clutter.rate > 0.0 else 0
    half = min(0.5 * sensor.fov, math.pi)
    if sensor.kind == "bearing":
        z = np.empty((k, 1))
        if k:
            z[:, 0] = wrap(rng.uniform(-half, half, k))
        return z
    z = np.empty((k, 2))
    if k:
        z[:, 0] = rng.uniform(0.0, clutter.range_limit(sensor), k)
        z[:, 1] = wrap(rng.uniform(-half, half, k))
    return z


def hide_ids(measurement: Measurement | None, sensor: SensorSpec, clutter: ClutterSpec,
             rng: np.random.Generator) -> Unlabeled | None:
    """Add clutter to one beacon sensor's reading, shuffle the rows and hide their IDs.

    ``measurement`` may be None (no beacon detected on this tick): clutter can still appear.
    Returns None when there is nothing at all to report. Draws, in order: the clutter
    (:func:`draw_clutter`), then one permutation of the rows.
    """
    if sensor.kind not in READING_KINDS:
        raise ValueError(f"hide_ids is for beacon sensors, not {sensor.kind!r}")
    d = 1 if sensor.kind == "bearing" else 2
    if measurement is not None and (measurement.kind != sensor.kind or measurement.sensor != sensor.name):
        raise ValueError(f"hide_ids: reading of {measurement.sensor!r} ({measurement.kind}) "
                         f"given with sensor {sensor.name!r} ({sensor.kind})")
    z_true = np.empty((0, d)) if measurement is None else np.asarray(measurement.z, dtype=float)
    ids_true = (np.empty(0, dtype=int) if measurement is None
                else np.asarray(measurement.beacon_ids, dtype=int))
    z_false = draw_clutter(sensor, clutter, rng)
    z = np.vstack([z_true, z_false])
    truth = np.concatenate([ids_true, np.full(z_false.shape[0], UNKNOWN_ID, dtype=int)])
    if z.shape[0] == 0:
        return None
    order = rng.permutation(z.shape[0])
    hidden = Measurement(sensor.name, sensor.kind, z[order], np.full(z.shape[0], UNKNOWN_ID, dtype=int))
    return Unlabeled(hidden, truth[order])


def unlabel(measurement: Measurement | None, sensor: SensorSpec, rng: np.random.Generator
            ) -> tuple[Measurement | None, np.ndarray | None]:
    """The simulation's step for a sensor with unknown correspondence: :func:`hide_ids` with
    the sensor's own ``clutter_rate``. Returns (what the filters see, the true IDs of its
    rows), or (None, None) when there is nothing to report."""
    u = hide_ids(measurement, sensor, ClutterSpec(sensor.clutter_rate), rng)
    return (None, None) if u is None else (u.measurement, u.true_ids)


def hide_ids_all(measurements: Iterable[Measurement], sensors: Iterable[SensorSpec],
                 clutter: dict[str, ClutterSpec], rng: np.random.Generator
                 ) -> tuple[tuple[Measurement, ...], dict[str, np.ndarray]]:
    """One tick's readings with unknown correspondence for the sensors named in ``clutter``.

    Sensors in ``clutter`` (by name; ``ClutterSpec()`` for no clutter) have their readings
    passed through :func:`hide_ids`, in the order of ``sensors`` (so the draws are
    deterministic); other readings and fixes pass through unchanged. Returns the readings a
    filter sees and, per unlabeled sensor, the true IDs of its rows. Only sensors that fire
    on this tick should be in ``sensors``.
    """
    by_name = {m.sensor: m for m in measurements}
    out: list[Measurement] = []
    truth: dict[str, np.ndarray] = {}
    for spec in sensors:
        m = by_name.pop(spec.name, None)
        if spec.name in clutter and spec.kind in READING_KINDS:
            u = hide_ids(m, spec, clutter[spec.name], rng)
            if u is not None:
                out.append(u.measurement)
                truth[spec.name] = u.true_ids
        elif m is not None:
            out.append(m)
    out.extend(by_name.values())
    return tuple(out), truth


def row_of_doors(x0: float, x1: float, y: float, n: int, first_id: int = 0) -> tuple[Beacon, ...]:
    """``n`` beacons evenly spaced on the segment from ``(x0, y)`` to ``(x1, y)`` [m]:
    seed 003's corridor whose doors look alike (every reading fits every door)."""
    if n < 1:
        raise ValueError(f"row_of_doors needs n >= 1, got {n}")
    xs = [x0] if n == 1 else list(np.linspace(x0, x1, n))
    return tuple(Beacon(first_id + k, float(x), float(y)) for k, x in enumerate(xs))


def symmetric_ring(cx: float, cy: float, radius: float, n: int, first_id: int = 0,
                   phase: float = 0.0) -> tuple[Beacon, ...]:
    """``n`` beacons on a circle of ``radius`` [m] about ``(cx, cy)``, at angles ``phase +
    2 pi k / n`` [rad]: a layout with n-fold symmetry, so that a robot turned by ``2 pi / n``
    about the centre sees exactly the same readings (n look-alike poses)."""
    if n < 1 or not radius > 0.0:
        raise ValueError(f"symmetric_ring needs n >= 1 and radius > 0, got n={n}, radius={radius}")
    a = phase + 2.0 * math.pi * np.arange(n) / n
    s, c = pm.sincos(a)   # portable: the beacons' places are part of the world
    return tuple(Beacon(first_id + k, float(cx + radius * ck), float(cy + radius * sk))
                 for k, (sk, ck) in enumerate(zip(s.tolist(), c.tolist(), strict=True)))
