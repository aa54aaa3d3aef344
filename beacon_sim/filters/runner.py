"""Feeds each simulation step to any number of filters, side by side on the same data,
and keeps each one's estimate history and cost.

A filter that raises, or returns a non-finite or malformed estimate, is switched off with
a message; the simulation and the other filters go on. That includes an object that does
not implement :class:`~beacon_sim.filters.base.Filter` at all (a student's class is only
duck-typed): its missing method raises on the first step and it is switched off. A filter
that is slow on every step gets a warning (:func:`note_step_time`); :func:`status_line` is
what the window and the terminal show for either.
"""

from __future__ import annotations

import time
import traceback
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from beacon_sim.core.types import Step
from beacon_sim.filters.base import Filter

#: ``FilterTrack.failed`` of a filter that was never built (``None`` given to the runner);
#: the caller usually replaces it with why construction failed.
NOT_BUILT = "not constructed"


#: A filter whose recent steps (predict + update + estimate) average more than this gets
#: ``track.slow_warning`` [ms].
SLOW_STEP_MS = 50.0
#: How many recent steps the average is taken over, and how many are needed before judging.
SLOW_WINDOW = 10
SLOW_MIN_STEPS = 3


def note_step_time(track: FilterTrack, step_ns: int) -> None:
    """Record one step's wall time [ns] on ``track`` and set ``track.slow_warning`` when the
    mean of the last ``SLOW_WINDOW`` steps, leaving out the slowest one, exceeds ``SLOW_STEP_MS``.

    One slow step (a first call that imports or allocates, a garbage collection) does not
    warn; a filter that is slow on every step does after ``SLOW_MIN_STEPS`` steps. The
    warning stays once given (it tells the user the filter cannot keep up in real time).
    """
    recent = track.recent_step_ns
    recent.append(int(step_ns))
    if len(recent) < SLOW_MIN_STEPS:
        return
    mean_ms = (sum(recent) - max(recent)) / (len(recent) - 1) / 1e6
    if mean_ms > SLOW_STEP_MS:
        track.slow_warning = (f"slow: {mean_ms:.0f} ms per step (over {SLOW_STEP_MS:.0f} ms; "
                              f"the simulation cannot run in real time)")


def status_line(track: FilterTrack) -> str | None:
    """What to show next to a filter's name: why it was switched off, or the slow warning."""
    if track.failed:
        return f"{track.name} switched off: {track.failed}"
    if getattr(track, "slow_warning", None):
        return f"{track.name} {track.slow_warning}"
    return None


@dataclass
class FilterTrack:
    """One filter in a run: the object (None when it could not be built), its history and
    its state."""

    name: str
    filter: Filter | None
    means: list[np.ndarray] = field(default_factory=list)
    covs: list[np.ndarray] = field(default_factory=list)
    ticks: list[int] = field(default_factory=list)
    step_ns: int = 0
    steps: int = 0
    failed: str | None = None
    traceback: str = ""
    slow_warning: str | None = None
    recent_step_ns: deque[int] = field(default_factory=lambda: deque(maxlen=SLOW_WINDOW))

    @property
    def us_per_step(self) -> float:
        """Mean wall time of predict + update + estimate [microseconds]."""
        return self.step_ns / 1e3 / max(self.steps, 1)


def check_estimate(mean: object, cov: object) -> str | None:
    """Why an estimate is unusable (wrong shape, non-finite, not symmetric PSD), or None."""
    mean = np.asarray(mean)
    cov = np.asarray(cov)
    if mean.shape != (3,) or cov.shape != (3, 3):
        return f"estimate() returned shapes {mean.shape} and {cov.shape}, expected (3,) and (3, 3)"
    if not (np.all(np.isfinite(mean)) and np.all(np.isfinite(cov))):
        return "estimate() returned NaN or infinity"
    scale = max(float(np.max(np.abs(cov))), 1e-12)
    if np.max(np.abs(cov - cov.T)) > 1e-6 * scale:
        return "covariance is not symmetric"
    if np.min(np.linalg.eigvalsh(0.5 * (cov + cov.T))) < -1e-9 * scale:
        return "covariance is not positive semi-definite"
    return None


class FilterRunner:
    """Runs several filters on the same steps.

    Parameters
    ----------
    filters : Mapping[str, Filter or None]
        Name -> a constructed, reset filter; None for one that could not be built (its
        track starts switched off with ``failed = NOT_BUILT``).
    """

    def __init__(self, filters: Mapping[str, Filter | None]):
        self.tracks = {name: FilterTrack(name, f, failed=None if f is not None else NOT_BUILT)
                       for name, f in filters.items()}

    def feed(self, step: Step) -> None:
        """Predict with the step's command, update with its measurements, record."""
        for track in self.tracks.values():
            f = track.filter
            if track.failed or f is None:
                continue
            t0 = time.perf_counter_ns()
            try:
                f.predict(step.control, step.dt)
                f.update(step.measurements)
                mean, cov = f.estimate()
            except Exception as exc:
                track.failed = f"{type(exc).__name__}: {exc}"
                track.traceback = traceback.format_exc()
                continue
            elapsed = time.perf_counter_ns() - t0
            track.step_ns += elapsed
            track.steps += 1
            note_step_time(track, elapsed)
            problem = check_estimate(mean, cov)
            if problem:
                track.failed = problem
                continue
            track.means.append(np.array(mean, dtype=float))
            track.covs.append(np.array(cov, dtype=float))
            track.ticks.append(step.tick)
