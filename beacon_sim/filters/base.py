"""The filter interface: a ``Protocol``, the context a filter is built from, belief types,
and a small base class that does the bookkeeping (docs/architecture.md, "Conventions").

A filter is any object with::

    reset(initial)            initial: GaussianBelief (tracking) or None (global)
    predict(control, dt)      motion update with the command [m/s, rad/s] over dt [s]
    update(measurements)      measurement update; the sequence may be empty
    estimate() -> (mean, cov) mean shape (3,) [m, m, rad], cov shape (3, 3)
    belief()                  GaussianBelief, ParticleBelief or GridBelief, for drawing

and optionally ``associations() -> {sensor: (beacon ID or None, ...)}``: for each reading
without IDs (unknown correspondence) of the last update, the beacon it was given to
(``FilterBase`` provides it for the built-in filters, docs/association.md).
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar, Protocol, runtime_checkable

import numpy as np

from beacon_sim.core.motion import MotionNoise
from beacon_sim.core.sensors import SensorSpec
from beacon_sim.core.types import Control, Measurement
from beacon_sim.core.world import World
from beacon_sim.errors import BeaconSimError

if TYPE_CHECKING:
    from beacon_sim.core.scenario import Scenario


class FilterError(BeaconSimError):
    """A filter was asked for something it cannot do (bad parameter, unknown sensor...)."""


@dataclass(frozen=True, eq=False)
class GaussianBelief:
    """A Gaussian over the pose: ``mean`` (3,) [m, m, rad], ``cov`` (3, 3)."""

    mean: np.ndarray
    cov: np.ndarray


@dataclass(frozen=True, eq=False)
class ParticleBelief:
    """Weighted samples: ``poses`` (N, 3) [m, m, rad], ``weights`` (N,) summing to one."""

    poses: np.ndarray
    weights: np.ndarray


@dataclass(frozen=True, eq=False)
class GridBelief:
    """A histogram over x-y (heading marginalised out) for drawing as a heat map.

    ``prob`` has shape (nx, ny), sums to one; cell (i, j) covers
    ``[xmin + i * cell, xmin + (i + 1) * cell) x [ymin + j * cell, ...)`` in metres.
    """

    prob: np.ndarray
    origin: tuple[float, float]
    cell: float


Belief = GaussianBelief | ParticleBelief | GridBelief


@dataclass(frozen=True, eq=False)
class FilterContext:
    """Everything a filter may know. It never holds the true pose.

    Attributes
    ----------
    name : str
        The filter's name in this run.
    world : World
        Bounds and the beacon map the filter is given: every beacon, or on an unknown map
        (SLAM, docs/slam.md) only the anchors.
    dt : float
        The simulation tick [s] (``predict`` also receives dt).
    motion_noise : MotionNoise
        The motion noise the filter is told (may differ from the truth's).
    sensors : tuple of SensorSpec
        The sensors with the noise the filter is told, by name.
    params : Mapping
        The filter's parameters (scenario ``[filters.NAME]`` and ``--set`` overrides).
    rng : numpy.random.Generator
        The only random generator the filter may use: its own stream of the run, derived
        from a hash of a key and the run's seed (``core.streams.filter_stream``), so it never
        holds the seed; ``grade`` keys it with a secret of the grade.
    map_known : bool
        False when the scenario withholds the beacon map (``[model] map = "unknown"``):
        ``world.beacons`` holds only the anchors and a filter must map the rest itself.
    """

    name: str
    world: World
    dt: float
    motion_noise: MotionNoise
    sensors: tuple[SensorSpec, ...]
    params: Mapping[str, Any] = field(default_factory=dict)
    rng: np.random.Generator = field(default_factory=lambda: np.random.default_rng(0))
    map_known: bool = True

    @classmethod
    def of_scenario(cls, scenario: Scenario, name: str, params: Mapping[str, Any],
                    rng: np.random.Generator, *, world: World | None = None) -> FilterContext:
        """The context of filter ``name`` on ``scenario``: what the scenario tells the filters
        (its filter world, map, tick, model motion noise and sensors), the filter's
        ``params`` and its own generator ``rng``; ``world``: instead of the scenario's filter
        world (a team's members share the team's). Every front end (run, eval, check, grade,
        the window, the team filters) builds a filter's context here."""
        return cls(name=name, world=scenario.filter_world if world is None else world,
                   dt=scenario.dt, motion_noise=scenario.model_motion_noise,
                   sensors=scenario.model_sensors, params=params, rng=rng,
                   map_known=scenario.map_known)

    def sensor(self, name: str) -> SensorSpec:
        """The spec (with the filter's noise) of the sensor that produced a measurement."""
        for s in self.sensors:
            if s.name == name:
                return s
        raise FilterError(f"no sensor named {name!r} in this filter's context")


@runtime_checkable
class Filter(Protocol):
    """What the runner, the window and the checker need from a filter."""

    def reset(self, initial: GaussianBelief | None) -> None: ...

    def predict(self, control: Control, dt: float) -> None: ...

    def update(self, measurements: Sequence[Measurement]) -> None: ...

    def estimate(self) -> tuple[np.ndarray, np.ndarray]: ...

    def belief(self) -> Belief: ...


@dataclass(frozen=True, eq=False)
class LandmarkMap:
    """A SLAM filter's map estimate (docs/slam.md), world frame.

    Attributes
    ----------
    ids : ndarray of int, shape (M,), or None
        The beacon ID each landmark stands for (known correspondence), or None when the
        filter made its landmarks up from unlabelled readings (unknown correspondence).
    means : ndarray, shape (M, 2) [m]
    covs : ndarray, shape (M, 2, 2) [m^2]
    """

    ids: np.ndarray | None
    means: np.ndarray
    covs: np.ndarray


@runtime_checkable
class MappingFilter(Filter, Protocol):
    """A SLAM filter: a :class:`Filter` whose estimate carries the map as well.
    ``estimate()`` stays the pose's (3,), (3, 3); ``landmarks()`` is the map."""

    def landmarks(self) -> LandmarkMap: ...


@runtime_checkable
class BatchedFilter(Protocol):
    """The batched form of a filter: one object running R Monte Carlo runs of it as arrays
    (``evaluation/montecarlo.py``; a built-in filter's record names its class).

    Attributes
    ----------
    mean : ndarray (R, 3) [m, m, rad]
    cov : ndarray (R, 3, 3)
    own_nis : bool
        True when ``update`` leaves the NIS of the tick's readings in ``last_nis``.
    last_nis : ndarray (R,) or None
    """

    mean: np.ndarray
    cov: np.ndarray
    own_nis: ClassVar[bool]
    last_nis: np.ndarray | None

    def predict(self, v: np.ndarray, w: np.ndarray, dt: float) -> None:
        """Every run's motion update with its command ``v``, ``w`` (R,) [m/s, rad/s]."""

    def update(self, readings: Any) -> None:
        """Every run's measurement update with the tick's readings, packed as
        ``filters.gaussian.measurements.StackedReadings`` (R runs x M slots)."""


@runtime_checkable
class Batchable(Protocol):
    """A filter that has a batched form."""

    @property
    def batch_blocker(self) -> str | None:
        """Why this filter, with its parameters and context, cannot be batched (None: it can)."""

    def batched(self, runs: int) -> BatchedFilter:
        """This filter, from its current belief, for ``runs`` runs at once."""


class _Estimating(Protocol):
    """A filter as far as :meth:`FilterBase.belief` needs it (the subclass defines
    ``estimate``)."""

    def estimate(self) -> tuple[np.ndarray, np.ndarray]: ...


class FilterBase:
    """Optional base class: stores the context, merges parameters with ``defaults``
    (unknown parameter names are an error with a "did you mean"), and draws a Gaussian
    belief from ``estimate()``.

    Class attributes
    ----------------
    defaults : dict
        Parameter names and default values.
    supports_global : bool
        True when ``reset(None)`` (a uniform belief over the world) is meaningful.
    """

    defaults: ClassVar[dict[str, Any]] = {}
    supports_global: ClassVar[bool] = False

    def __init__(self, ctx: FilterContext):
        self.ctx = ctx
        self.params = self.merge_params(ctx.params)

    @classmethod
    def merge_params(cls, given: Mapping[str, Any]) -> dict[str, Any]:
        out = dict(cls.defaults)
        for key, value in given.items():
            if key not in cls.defaults:
                hint = difflib.get_close_matches(key, list(cls.defaults), n=1)
                extra = f" (did you mean {hint[0]!r}?)" if hint else ""
                known = ", ".join(sorted(cls.defaults)) or "none"
                raise FilterError(
                    f"{cls.__name__}: unknown parameter {key!r}{extra}; known: {known}")
            default = cls.defaults[key]
            if isinstance(default, bool) != isinstance(value, bool) or (
                    isinstance(default, int | float) and not isinstance(value, int | float)):
                raise FilterError(f"{cls.__name__}: parameter {key} = {value!r}: expected "
                                  f"a {type(default).__name__} like {default!r}")
            out[key] = type(default)(value) if isinstance(default, float) else value
        return out

    def belief(self: _Estimating) -> Belief:
        mean, cov = self.estimate()
        return GaussianBelief(mean, cov)

    def associations(self) -> dict[str, tuple[int | None, ...]]:
        """Per sensor with unknown correspondence, the beacon ID (or None: clutter) each row
        of its reading in the last update was given to; {} when there was none."""
        wiring = self.__dict__.get("_association")
        return {} if wiring is None else wiring.report(self)


def broad_gaussian(world: World) -> GaussianBelief:
    """The Gaussian a tracking filter gets when asked for a global (uniform) belief: the
    centre of the world with the variance of a uniform distribution over it."""
    xmin, ymin, xmax, ymax = world.bounds
    mean = np.array([(xmin + xmax) / 2, (ymin + ymax) / 2, 0.0])
    cov = np.diag([(xmax - xmin) ** 2 / 12, (ymax - ymin) ** 2 / 12, math.pi**2 / 3])
    return GaussianBelief(mean, cov)
