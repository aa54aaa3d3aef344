"""A Gaussian filter's run smoothed: the same filter fed the same ticks again, its moments
recorded (``filters/smoothing/recorder.py``), then the Rauch-Tung-Striebel backward pass.

The filter is rebuilt exactly as the run built it (``loading.build_filter``: its scenario,
seed, name and parameters), so the filtered track it gives again is the run's, bit for bit
(tests/filters/test_smoothing.py), and the run itself is never touched. Only filters whose belief is
one Gaussian predicted with the velocity model are smoothed: the EKF and the UKF (and a
student's subclass of either).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from beacon_sim.core.scenario import Scenario
from beacon_sim.core.types import Step
from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter
from beacon_sim.filters.gaussian.ukf import UnscentedKalmanFilter
from beacon_sim.filters.smoothing.recorder import MomentRecorder
from beacon_sim.hosting.loading import build_filter, filter_display_name, load_filter_class
from beacon_sim.io.recording import Recording
from beacon_sim.runs.replay import replay_recording

#: The filter classes a run can be smoothed for (their subclasses too).
SMOOTHABLE = (ExtendedKalmanFilter, UnscentedKalmanFilter)


class NotSmoothable(ValueError):
    """The filter is not one Gaussian over the pose predicted with the velocity model."""


@dataclass(frozen=True)
class SmoothedTrack:
    """A filter's run, filtered and smoothed, at ticks ``ticks`` (T + 1,) (tick 0: the
    initial belief). Means (T + 1, 3) [m, m, rad], covariances (T + 1, 3, 3)."""

    name: str
    ticks: np.ndarray
    filtered_means: np.ndarray
    filtered_covs: np.ndarray
    smoothed_means: np.ndarray
    smoothed_covs: np.ndarray

    def at(self, tick: int) -> int | None:
        """The row of ``tick`` (None when the track does not hold it)."""
        k = int(np.searchsorted(self.ticks, tick))
        return k if k < len(self.ticks) and int(self.ticks[k]) == tick else None


def smoothable(spec: str) -> bool:
    """Whether filter ``spec`` (a built-in name, module or file) can be smoothed."""
    try:
        cls = load_filter_class(spec)
    except Exception:  # a filter that does not load is not smoothed (the run says why)
        return False
    return isinstance(cls, type) and issubclass(cls, SMOOTHABLE)


def smooth_steps(scenario: Scenario, spec: str, seed: int, steps: Sequence[Step],
                 params: dict[str, Any] | None = None, name: str | None = None) -> SmoothedTrack:
    """Filter ``spec`` fed ``steps`` of a run of ``scenario`` with ``seed`` again, and
    smoothed over the whole run (the last segment, when the filter was reset)."""
    if not smoothable(spec):
        raise NotSmoothable(f"{filter_display_name(spec)}: no smoother (the smoothers take a Gaussian "
                            f"filter with the velocity model: ekf, ukf)")
    name = name or filter_display_name(spec)
    rec = MomentRecorder(build_filter(spec, scenario, seed, name, params))
    for st in steps:
        rec.predict(st.control, st.dt)
        rec.update(st.measurements)
    seg = rec.segments[-1]
    ticks, fm, fc = seg.filtered()
    _, sm, sc = seg.smoothed()
    return SmoothedTrack(name, ticks, fm, fc, sm, sc)


def smooth_recording(recording: Recording, specs: Sequence[str],
                     params: dict[str, dict[str, Any]] | None = None) -> dict[str, SmoothedTrack]:
    """Every smoothable filter of ``specs`` on a single robot's recording, smoothed: the
    recording replayed headless (and verified), then :func:`smooth_steps` on its ticks.
    The smoother is fed the recorded ticks from the start; a user's reset of a filter in
    the window is not in it."""
    if recording.is_team:
        raise NotSmoothable("--smooth: a single robot's recording only (this one holds a team)")
    result = replay_recording(recording, list(specs), params)
    out = {}
    for spec in specs:
        if smoothable(spec):
            name = filter_display_name(spec)
            out[name] = smooth_steps(result.scenario, spec, result.seed, result.steps,
                                     (params or {}).get(name), name)
    return out


__all__ = ["SMOOTHABLE", "NotSmoothable", "SmoothedTrack", "smooth_recording", "smooth_steps", "smoothable"]
