"""The smoothers: the whole trajectory re-estimated from all the data (docs/smoothing.md).

A filter's estimate at tick k uses the readings up to k; a smoother's uses every reading of
the run, before and after k. Read in this order:

- ``rts.py``: the fixed-interval Rauch-Tung-Striebel smoother, one backward pass over a
  Gaussian filter's predicted and updated moments (the maths, on arrays);
- ``recorder.py``: :class:`MomentRecorder`, a wrapper that records those moments from any
  filter with a Gaussian ``estimate()`` without changing what the filter computes;
- ``fixed_lag.py``: :class:`FixedLagSmoother`, the same backward pass over the last L ticks,
  run live: the estimate of tick k - L from the readings up to k.

The family stands on the core and the filters' shared home only (the filter interface); it
never imports another family.
"""

from beacon_sim.filters.smoothing.fixed_lag import FixedLagSmoother
from beacon_sim.filters.smoothing.recorder import MomentRecorder, Moments
from beacon_sim.filters.smoothing.rts import rts_smooth, velocity_jacobian

__all__ = ["FixedLagSmoother", "MomentRecorder", "Moments", "rts_smooth", "velocity_jacobian"]
