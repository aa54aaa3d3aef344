"""Recording a Gaussian filter's predicted and updated moments, for the smoothers.

:class:`MomentRecorder` wraps any filter whose ``estimate()`` is a Gaussian (mean, cov) and
that predicts with the velocity model (the EKF, the UKF): it passes every call through
unchanged and reads ``estimate()`` after each ``predict`` and ``update``, so the filter's
results are its own, bit for bit (``estimate()`` only reads the belief). It also keeps each
tick's motion Jacobian ``F`` at the mean the prediction started from, which the
Rauch-Tung-Striebel gain needs; for a filter that says how its prediction is correlated with
its belief (``motion_cross_covariance(control, dt)``, the UKF's sigma points), the
statistical linearisation of that instead (``rts.statistical_jacobian``: the unscented RTS
gain).

A ``reset`` (a user's reset in the window) starts a new segment: a smoother never joins two
beliefs the filter did not join itself.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from beacon_sim.core.types import Control, Measurement
from beacon_sim.filters.smoothing.rts import rts_smooth, statistical_jacobian, velocity_jacobian


@dataclass
class Moments:
    """One segment of a filter's run: tick ``first_tick``'s belief and, for each tick after
    it, the predicted and updated moments and the motion Jacobian (see ``rts.rts_smooth``).

    ``ticks[k]``: the tick of ``means[k]`` (``ticks[0] = first_tick``)."""

    first_tick: int
    ticks: list[int] = field(default_factory=list)
    means: list[np.ndarray] = field(default_factory=list)
    covs: list[np.ndarray] = field(default_factory=list)
    pred_means: list[np.ndarray] = field(default_factory=list)
    pred_covs: list[np.ndarray] = field(default_factory=list)
    jacobians: list[np.ndarray] = field(default_factory=list)

    def smoothed(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(ticks (T + 1,), means (T + 1, 3), covs (T + 1, 3, 3))``: the RTS smoother's."""
        n = len(self.pred_means)
        ms, Ps = rts_smooth(np.array(self.means[:n + 1]), np.array(self.covs[:n + 1]),
                            np.array(self.pred_means).reshape(n, 3),
                            np.array(self.pred_covs).reshape(n, 3, 3),
                            np.array(self.jacobians).reshape(n, 3, 3))
        return np.array(self.ticks[:n + 1]), ms, Ps

    def filtered(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(ticks, means, covs)`` of the filter itself, as :meth:`smoothed`."""
        n = len(self.pred_means)
        return np.array(self.ticks[:n + 1]), np.array(self.means[:n + 1]), np.array(self.covs[:n + 1])


def _gaussian(est: Any) -> tuple[np.ndarray, np.ndarray]:
    mean, cov = est
    return np.array(mean, dtype=float).reshape(3), np.array(cov, dtype=float).reshape(3, 3)


class MomentRecorder:
    """A filter with its moments recorded (the :class:`~beacon_sim.filters.base.Filter`
    methods pass through; ``segments`` holds the record). ``tick`` counts the predictions
    since tick ``first_tick`` (the tick of the belief the filter holds when wrapped)."""

    def __init__(self, flt: Any, first_tick: int = 0):
        self.filter = flt
        self.tick = first_tick
        self.segments: list[Moments] = []
        self._start(first_tick)

    def _start(self, tick: int) -> None:
        mean, cov = _gaussian(self.filter.estimate())
        self.segments.append(Moments(tick, [tick], [mean], [cov]))

    # -- the filter interface -----------------------------------------------------------
    def reset(self, initial: Any) -> None:
        self.filter.reset(initial)
        self._start(self.tick)

    def predict(self, control: Control, dt: float) -> None:
        seg = self.segments[-1]
        cross = getattr(self.filter, "motion_cross_covariance", None)
        if callable(cross):   # read before the prediction: it reads the belief it starts from
            F = statistical_jacobian(np.asarray(cross(control, dt), dtype=float), seg.covs[-1])
        else:
            F = velocity_jacobian(seg.means[-1], float(control.v), dt)
        self.filter.predict(control, dt)
        self.tick += 1
        mean, cov = _gaussian(self.filter.estimate())
        seg.jacobians.append(F)
        seg.pred_means.append(mean)
        seg.pred_covs.append(cov)
        seg.ticks.append(self.tick)
        seg.means.append(mean)   # replaced by the update's
        seg.covs.append(cov)

    def update(self, measurements: Sequence[Measurement]) -> None:
        self.filter.update(measurements)
        seg = self.segments[-1]
        seg.means[-1], seg.covs[-1] = _gaussian(self.filter.estimate())

    def estimate(self) -> Any:
        return self.filter.estimate()

    def belief(self) -> Any:
        return self.filter.belief()

    def __getattr__(self, name: str) -> Any:  # the rest of the filter's attributes
        if name == "filter":
            raise AttributeError(name)
        return getattr(self.filter, name)


__all__ = ["MomentRecorder", "Moments"]
