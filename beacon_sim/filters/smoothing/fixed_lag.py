"""The fixed-lag smoother: tick k - L's estimate from the readings up to tick k, live.

:class:`FixedLagSmoother` wraps a Gaussian filter (EKF, UKF) in a
:class:`~beacon_sim.filters.smoothing.recorder.MomentRecorder` and, after each tick, runs the
Rauch-Tung-Striebel backward pass over the last ``lag`` ticks only (``rts.rts_step``, L
steps: O(L) per tick). The filter itself is unchanged (``estimate()`` is still the filter's);
:meth:`lagged` is the smoothed belief ``lag`` ticks back. With ``lag`` at least the run's
length it is the fixed-interval smoother's estimate at that tick.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from beacon_sim.core.types import Control, Measurement
from beacon_sim.filters.smoothing.recorder import MomentRecorder
from beacon_sim.filters.smoothing.rts import rts_step


class FixedLagSmoother:
    """A filter with a fixed-lag smoother beside it.

    Parameters
    ----------
    flt : a filter with a Gaussian ``estimate()`` that predicts with the velocity model.
    lag : int
        L >= 1 ticks: :meth:`lagged` is the belief of tick k - L given the readings up to k.
    """

    def __init__(self, flt: Any, lag: int, first_tick: int = 0):
        if int(lag) != lag or lag < 1:
            raise ValueError(f"fixed-lag smoother: lag {lag!r}: expected a whole number of ticks >= 1")
        self.lag = int(lag)
        self.recorder = MomentRecorder(flt, first_tick)

    def reset(self, initial: Any) -> None:
        self.recorder.reset(initial)

    def predict(self, control: Control, dt: float) -> None:
        self.recorder.predict(control, dt)
        self._trim()

    def update(self, measurements: Sequence[Measurement]) -> None:
        self.recorder.update(measurements)

    def estimate(self) -> Any:
        return self.recorder.estimate()

    def belief(self) -> Any:
        return self.recorder.belief()

    def _trim(self) -> None:
        """Keep the last ``lag + 1`` beliefs of the segment (and what links them)."""
        seg = self.recorder.segments[-1]
        del self.recorder.segments[:-1]
        extra = len(seg.pred_means) - self.lag
        if extra > 0:
            for lst in (seg.ticks, seg.means, seg.covs, seg.pred_means, seg.pred_covs, seg.jacobians):
                del lst[:extra]

    def lagged(self) -> tuple[int, np.ndarray, np.ndarray]:
        """``(tick, mean (3,), cov (3, 3))``: the smoothed belief of the oldest tick kept (k -
        L once L ticks have run; earlier, the segment's first), from every reading so far."""
        seg = self.recorder.segments[-1]
        n = len(seg.pred_means)
        m, P = seg.means[n].copy(), seg.covs[n].copy()
        for k in range(n - 1, -1, -1):
            m, P = rts_step(seg.means[k], seg.covs[k], seg.jacobians[k], seg.pred_means[k], seg.pred_covs[k],
                            m, P)
        return seg.ticks[0], m, P


__all__ = ["FixedLagSmoother"]
