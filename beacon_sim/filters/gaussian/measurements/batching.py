"""The Gaussian filters' R-run forms: ``BatchedGaussian`` (R means and covariances) and
``BatchableFilter``, a filter that declares which parameters its batched form reproduces."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from beacon_sim.core.motion import MotionNoise
from beacon_sim.filters.base import FilterBase
from beacon_sim.filters.gaussian.measurements.readings import KINDS, StackedReadings


class BatchedGaussian:
    """One Gaussian filter for R runs: ``mean`` (R, 3) [m, m, rad], ``cov`` (R, 3, 3).

    ``predict(v, w, dt)`` takes the commands (R,) [m/s, rad/s]; ``update(st)`` the tick's
    readings (R, M) from a :class:`SlotPacker`.
    """

    #: True when ``update`` leaves the NIS of the tick's readings in ``last_nis`` (for free).
    own_nis: ClassVar[bool] = False

    def __init__(self, mean0: np.ndarray, cov0: np.ndarray, runs: int, noise: MotionNoise):
        self.mean = np.tile(np.asarray(mean0, dtype=float), (runs, 1))
        self.cov = np.tile(np.asarray(cov0, dtype=float), (runs, 1, 1))
        self.noise = noise
        self.last_nis: np.ndarray | None = None

    def predict(self, v: np.ndarray, w: np.ndarray, dt: float) -> None:
        raise NotImplementedError

    def update(self, st: StackedReadings) -> None:
        """No measurement update (dead reckoning)."""


class BatchableFilter(FilterBase):
    """A filter with a form that runs R runs at once (:meth:`batched`).

    ``batch_params`` (declared by the class itself) names the parameters that form
    reproduces: None = any value, else the only value it does. A parameter not named there,
    a subclass that does not declare its own, a motion noise other than a plain
    ``MotionNoise`` or a sensor kind without slots keep the filter to one run at a time.
    """

    batch_params: ClassVar[dict[str, Any]] = {}

    @property
    def batch_blocker(self) -> str | None:
        """Why this filter has no batched form (None: :meth:`batched` reproduces it)."""
        cls = type(self)
        if "batch_params" not in vars(cls):
            return f"{cls.__name__} has no batched form"
        for key, value in self.params.items():
            if key not in cls.batch_params:
                return f"parameter {key} is not batched"
            only = cls.batch_params[key]
            if only is not None and value != only:
                return f"{key} = {value!r} is not batched"
        if type(self.ctx.motion_noise) is not MotionNoise:
            return "the motion noise is not a plain MotionNoise"
        for s in self.ctx.sensors:
            if s.kind not in KINDS:
                return f"sensor kind {s.kind!r} is not batched"
            if s.correspondence != "known":  # the batched runs carry beacon IDs
                return f"sensor {s.name!r} has unknown correspondence (not batched)"
        return None

    def batched(self, runs: int) -> BatchedGaussian:
        """This filter, from its current belief, for ``runs`` runs at once."""
        raise NotImplementedError


__all__ = ["BatchableFilter", "BatchedGaussian"]
