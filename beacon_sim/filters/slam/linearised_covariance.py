"""FastSLAM's reported uncertainty with ``covariance = "linearised"`` (``slam/fastslam.py``):
EKF-SLAM's covariance recursion run beside the particles, and the tick's readings without
those the known-ID gate dropped (:func:`without_rows`), which the recursion must not see."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np

from beacon_sim.core.clutter import UNKNOWN_ID
from beacon_sim.core.types import Control, Measurement
from beacon_sim.filters.base import FilterContext, FilterError, GaussianBelief
from beacon_sim.filters.slam.base import SLAM_KINDS


def without_rows(measurements: Sequence[Measurement], rows: Sequence[int]) -> list[Measurement]:
    """The tick's measurements with the beacon readings numbered ``rows`` taken out (the
    numbering of ``SlamFilterBase.readings``: the SLAM kinds' rows in order)."""
    out = list(measurements)
    if not rows:
        return out
    drop = set(rows)
    first = 0
    for q, m in enumerate(out):
        if m.kind not in SLAM_KINDS:
            continue
        n = len(m.beacon_ids)
        keep = np.array([first + r not in drop for r in range(n)], dtype=bool)
        if not keep.all():
            out[q] = replace(m, z=np.asarray(m.z)[keep], beacon_ids=np.asarray(m.beacon_ids)[keep])
        first += n
    return out


class LinearisedCovariance:
    """FastSLAM's reported uncertainty with ``covariance = "linearised"``: EKF-SLAM's
    covariance recursion (``ekf_slam.EKFSLAM``, the same readings, the same models) whose
    mean is reset to the particles' mean before each prediction and update, so only its
    covariance P is kept: the Jacobians F, H and the new-landmark G are those at FastSLAM's
    estimate. It is the covariance a Gaussian filter at that estimate would carry, cross terms
    between the pose and every landmark included, which the particles lose to resampling
    (Bailey, Nieto and Nebot 2006). Known IDs: a reading of an unlabelled landmark switches
    it off (``ok`` False) and the particle set's moments are reported."""

    def __init__(self, ctx: FilterContext, initial: GaussianBelief | None):
        from beacon_sim.filters.slam.ekf_slam import EKFSLAM  # the recursion itself, not copied

        self.ekf = EKFSLAM(replace(ctx, params={}))
        self.ekf.reset(initial)
        self.ok = True

    def _sync(self, pose: np.ndarray, means: dict[int, np.ndarray]) -> None:
        ekf = self.ekf
        ekf.mu[:3] = pose
        for bid, j in ekf.index.items():
            m = means.get(bid)
            if m is not None:
                ekf.mu[3 + 2 * j:5 + 2 * j] = m

    def predict(self, pose: np.ndarray, control: Control, dt: float) -> None:
        if self.ok:
            self.ekf.mu[:3] = pose
            self._guarded(lambda: self.ekf.predict(control, dt))

    def update(self, pose: np.ndarray, means: dict[int, np.ndarray], measurements: Sequence[Measurement]
               ) -> None:
        if not self.ok:
            return
        if any(np.any(np.asarray(m.beacon_ids) == UNKNOWN_ID) for m in measurements if m.kind in SLAM_KINDS):
            self.ok = False
            return
        self._sync(pose, means)
        self._guarded(lambda: self.ekf.update(measurements))

    def _guarded(self, step: Callable[[], None]) -> None:
        """Run one step; if it fails or leaves P not finite, switch the linearised covariance
        off (the particle set's is reported from then on) rather than the filter."""
        try:
            with np.errstate(all="ignore"):
                step()
        except (FilterError, np.linalg.LinAlgError, ValueError):
            self.ok = False
            return
        if not np.all(np.isfinite(self.ekf.P)):
            self.ok = False


__all__ = ["LinearisedCovariance", "without_rows"]
