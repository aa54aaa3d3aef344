"""Feeds each simulation step to any number of filters, side by side on the same data,
and keeps each one's estimate history and cost.

A filter that raises, or returns a non-finite or malformed estimate, is switched off with
a message; the simulation and the other filters go on. That includes an object that does
not implement :class:`~beacon_sim.filters.base.Filter` at all (a student's class is only
duck-typed): its missing method raises on the first step and it is switched off. A filter
that is slow on every step gets a warning (:func:`note_step_time`); :func:`status_line` is
what the window and the terminal show for either.

The runner is one of three rooms (a filter host with a seam): the guard
(:mod:`beacon_sim.hosting.guard`, what a filter returned), the watchdog
(:mod:`beacon_sim.hosting.watchdog`, time limits and interrupts) and the host
(:mod:`beacon_sim.hosting.host`, the one guarded-call ladder). Their names are re-exported
here, where other modules have always imported them from.
"""

from __future__ import annotations

import math
import threading
import time
import traceback
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from beacon_sim.core.types import Step
from beacon_sim.filters.base import Filter
from beacon_sim.hosting.guard import (
    MAX_COV,
    MAX_MEAN,
    check_estimate,
    shape_text,
    validate_belief,
    validate_estimate,
)
from beacon_sim.hosting.host import call_guarded, failure_of, guarded_call, run_filter_code
from beacon_sim.hosting.watchdog import (
    CPU_BACKSTOP_FACTOR,
    CPU_BACKSTOP_S,
    FilterExit,
    FilterTimeout,
    StepWatch,
    exit_text,
    failure_line,
    is_filter_failure,
    note_user_interrupt,
    one_line,
    settle_slot,
    step_slot,
    time_limit,
    user_interrupted,
)

#: ``FilterTrack.failed`` of a filter that was never built (``None`` given to the runner);
#: the caller usually replaces it with why construction failed.
NOT_BUILT = "not constructed"


#: The longest a step (predict + update + estimate) may take in a headless run and in the
#: window before the filter is stopped [s]: far beyond real time, not a benchmark.
HEADLESS_STEP_LIMIT_S = 10.0
#: The window's limit on a step and on any other call into a filter (belief, estimate,
#: reset), in CPU time of the filter's own thread [s] (``cpu_limits``): a busy machine makes
#: a step wait for a core, which costs wall time but no CPU time, so the machine's load never
#: switches a filter off. Generous for the built-in filters, whose heaviest step on a shipped
#: scenario uses about 0.06 s (mcl with 50,000 particles); a student's endless loop freezes
#: the window this long. Code that sleeps is stopped by the wall-time backstop only
#: (``CPU_BACKSTOP_FACTOR`` times this plus ``CPU_BACKSTOP_S``).
WINDOW_STEP_LIMIT_S = 1.0

#: A filter whose recent steps (predict + update + estimate) average more than this gets
#: ``track.slow_warning`` [ms].
SLOW_STEP_MS = 50.0
#: How many recent steps the average is taken over, and how many are needed before judging.
SLOW_WINDOW = 10
SLOW_MIN_STEPS = 3
_SLOW_NS = SLOW_STEP_MS * 1e6  # [ns]
_INF = math.inf
_get_ident = threading.get_ident
_monotonic = time.monotonic  # the watchdog's clock


def note_step_time(track: FilterTrack, step_ns: int) -> None:
    """Record one step's time [ns] on ``track`` (wall time; a window's worker gives its thread's
    CPU time: ``FilterRunner.slow_by_cpu``) and set ``track.slow_warning`` when the
    mean of the last ``SLOW_WINDOW`` steps, leaving out the slowest one, exceeds ``SLOW_STEP_MS``.

    One slow step (a first call that imports or allocates, a garbage collection) does not
    warn; a filter that is slow on every step does after ``SLOW_MIN_STEPS`` steps. The
    warning stays once given (it tells the user the filter cannot keep up in real time).
    The sum of the recent steps is kept as it goes (exact integers), and the slowest one is
    looked for only when that sum alone is over the line: the same verdict for less work.
    """
    recent = track.recent_step_ns
    step_ns = int(step_ns)
    if len(recent) == recent.maxlen:
        track.recent_sum_ns -= recent[0]
    recent.append(step_ns)
    track.recent_sum_ns += step_ns
    n = len(recent)
    if n < SLOW_MIN_STEPS or track.recent_sum_ns <= SLOW_STEP_MS * 1e6 * (n - 1):
        return
    mean_ms = (track.recent_sum_ns - max(recent)) / (n - 1) / 1e6
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
    # Every estimate in a headless run (the metrics need them all); the last ``keep`` only
    # in a window's session (see :func:`bounded_track`), so its memory stays bounded.
    means: list[np.ndarray] | deque[np.ndarray] = field(default_factory=list)
    covs: list[np.ndarray] | deque[np.ndarray] = field(default_factory=list)
    ticks: list[int] | deque[int] = field(default_factory=list)
    step_ns: int = 0
    steps: int = 0
    failed: str | None = None
    traceback: str = ""
    failed_time_s: float | None = None  # simulated time of the step that failed [s]
    slow_warning: str | None = None
    recent_step_ns: deque[int] = field(default_factory=lambda: deque(maxlen=SLOW_WINDOW))
    recent_sum_ns: int = 0  # the sum of recent_step_ns [ns], kept by note_step_time
    #: The filter time charged against a run limit [ns]: the filter thread's CPU time under
    #: CPU limits (a verdict that does not depend on the machine's load), else ``step_ns``.
    charged_ns: int = 0

    @property
    def us_per_step(self) -> float:
        """Mean wall time of predict + update + estimate [microseconds]."""
        return self.step_ns / 1e3 / max(self.steps, 1)


def failure_text(track: FilterTrack) -> str | None:
    """``reason (at 3.00 s)`` for a failed track, None for a working one."""
    if not track.failed:
        return None
    at = f" (at {track.failed_time_s:.2f} s)" if track.failed_time_s is not None else ""
    return track.failed + at


def bounded_track(name: str, flt: Filter | None, keep: int | None, **fields: Any) -> FilterTrack:
    """A track that keeps every estimate (``keep`` None) or only the last ``keep`` of them
    (means, covariances and ticks in ring buffers: the window's sessions)."""
    if keep is None:
        return FilterTrack(name, flt, **fields)
    return FilterTrack(name, flt, deque(maxlen=keep), deque(maxlen=keep), deque(maxlen=keep), **fields)


class FilterRunner:
    """Runs several filters on the same steps.

    Parameters
    ----------
    filters : Mapping[str, Filter or None]
        Name -> a constructed, reset filter; None for one that could not be built (its
        track starts switched off with ``failed = NOT_BUILT``).

    step_limit_s : float, optional
        A step (predict + update + estimate) longer than this [s] wall time stops the
        filter ("time limit"); None: no limit.
    run_limit_s : float, optional
        A filter whose steps add up to more than this [s] wall time is stopped.
    keep : int, optional
        Keep only the last ``keep`` estimates of each filter (a window's session, whose
        memory must not grow with time); None (headless runs): keep them all.
    cpu_limits : bool
        The step limit counts the filter thread's CPU time, not wall time (a verdict that
        does not depend on the machine's load; see :class:`time_limit`). Default False:
        wall time, what a window must keep up with.
    """

    #: Filters (by name) whose estimate after predict and before update is copied, each
    #: step, into ``priors[name]`` as (mean (3,), cov (3, 3)): the window's step view.
    #: Empty (the default): no extra call; the filters' results are the same either way.
    keep_prior: frozenset[str] = frozenset()
    priors: dict[str, tuple[np.ndarray, np.ndarray]]

    def __init__(self, filters: Mapping[str, Filter | None], step_limit_s: float | None = None,
                 run_limit_s: float | None = None, keep: int | None = None, cpu_limits: bool = False):
        self.keep = keep
        self.cpu_limits = cpu_limits
        self.tracks = {name: bounded_track(name, f, keep, failed=None if f is not None else NOT_BUILT)
                       for name, f in filters.items()}
        self.step_limit_s = step_limit_s
        self.run_limit_s = run_limit_s
        self._watch = StepWatch(cpu_limits)  # one for every step, armed in place
        self._watch_cpu = cpu_limits
        #: The slow warning (:func:`note_step_time`) on the filter thread's CPU time instead of
        #: the wall clock: on a window's worker thread, whose wall time includes waiting for
        #: the interpreter lock while the window draws (``runs/filter_worker``).
        self.slow_by_cpu = False

    def fail(self, name: str, reason: str, tb: str = "", time_s: float | None = None) -> None:
        """Switch ``name`` off with ``reason`` (one line), at simulated time ``time_s`` [s]."""
        track = self.tracks[name]
        if track.failed and track.failed != NOT_BUILT:
            return
        track.failed, track.traceback, track.failed_time_s = reason, tb, time_s

    def _limit(self, track: FilterTrack) -> tuple[float | None, bool]:
        """The time this track's next step may take [s], and whether that is what is left
        of the run limit (the step limit, or what is left of the run limit, whichever is
        shorter)."""
        step, run = self.step_limit_s, self.run_limit_s
        if run is not None:
            left = run - (track.charged_ns if self.cpu_limits else track.step_ns) / 1e9
            if step is None or left < step:
                return left, True
        return step, False

    def _over(self, of_run: bool) -> str:
        """The message of a step stopped by its time limit (see :meth:`_limit`)."""
        cpu = self.cpu_limits   # a CPU-time limit says so: the wall clock may show far more
        if of_run:
            return f"time limit: over {self.run_limit_s:g} s of filter {'CPU ' if cpu else ''}time in the run"
        if self.step_limit_s is None:
            return ""
        return f"time limit: a step took over {self.step_limit_s:g} s{' of CPU' if cpu else ''}"

    def _step(self, track: FilterTrack, f: Filter, step: Step) -> object:
        """predict, (the prior for the step view), update, estimate: one step of one filter."""
        f.predict(step.control, step.dt)
        if track.name in self.keep_prior:  # the step view: the belief after predict
            prior = validate_estimate(f.estimate())  # the one guard
            if isinstance(prior, str):
                raise ValueError(f"after predict: {prior}")
            self.priors[track.name] = prior
        f.update(step.measurements)
        return f.estimate()

    def feed(self, step: Step) -> None:
        """Predict with the step's command, update with its measurements, record.

        The per-step work around a filter is kept small (``benchmarks/bench_runner.py``):
        the thread's :class:`StepWatch` entry armed and ended in place (the same protocol, no
        object, no lock unless the watchdog fired), the ladder of :func:`call_guarded` inlined,
        the guard's fast path for the usual float64 estimate, whose arrays are kept without a
        copy when nothing else refers to them (``sole=True``). A step view (``keep_prior``),
        or another limit armed around the loop, takes the general way (:meth:`_general`)."""
        if self._watch_cpu is not self.cpu_limits:  # cpu_limits changed since: a watch to match
            self._watch = StepWatch(self.cpu_limits)
            self._watch_cpu = self.cpu_limits
        cpu = self._watch.cpu
        clock = time.perf_counter_ns
        plain = not self.keep_prior
        no_run_limit, step_limit = self.run_limit_s is None, self.step_limit_s
        control, dt, measurements = step.control, step.dt, step.measurements
        by_cpu = self.slow_by_cpu
        guard = validate_estimate
        tid = _get_ident()  # every filter of a step runs in this thread
        for track in self.tracks.values():
            f = track.filter
            if track.failed or f is None:
                continue
            if no_run_limit:  # the usual case, without the method call
                limit, of_run = step_limit, False
            else:
                limit, of_run = self._limit(track)
            entry, seconds = None, 0.0
            if limit is not None and -_INF < limit < _INF:  # a limit: the thread's own entry
                seconds = limit if limit > 0.0 else 0.0
                entry = step_slot(tid)
                if entry is None:  # another limit is armed around us: StepWatch nests
                    plain = False
            if not plain:
                est = self._general(track, f, step, limit, of_run)
                if est is _FAILED:
                    continue
            else:
                cpu0 = 0 if no_run_limit and not by_cpu else time.thread_time_ns()
                t0 = clock()
                try:
                    if entry is not None:  # StepWatch.__enter__, inline
                        if cpu:
                            entry[3] = -1.0
                            entry[4] = -1.0
                            entry[2] = seconds
                            entry[0] = _monotonic() + seconds * CPU_BACKSTOP_FACTOR + CPU_BACKSTOP_S
                        else:
                            entry[0] = _monotonic() + seconds
                        f.predict(control, dt)
                        f.update(measurements)
                        est = f.estimate()
                        entry[0] = _INF  # StepWatch.__exit__ inline (in the try: a late raise is this step's)
                        entry[2] = -1.0
                        if entry[1]:
                            settle_slot(entry)
                    else:
                        f.predict(control, dt)
                        f.update(measurements)
                        est = f.estimate()
                except BaseException as exc:  # the ladder of host.call_guarded, inline
                    if entry is not None:
                        settle_slot(entry)  # nothing re-fired after the step
                    self._stopped(track, exc, limit, of_run, t0, cpu0, step.time)
                    continue
                elapsed = clock() - t0
                track.step_ns += elapsed
                if not no_run_limit:
                    track.charged_ns += time.thread_time_ns() - cpu0
                track.steps += 1
                if by_cpu:  # the slow warning on this thread's CPU time
                    elapsed = time.thread_time_ns() - cpu0
                # note_step_time's usual case inline: the recent steps' sum is under the line
                recent = track.recent_step_ns
                n = len(recent)
                if n == SLOW_WINDOW:
                    total = track.recent_sum_ns - recent[0] + elapsed
                else:
                    total = track.recent_sum_ns + elapsed
                    n += 1
                if n < SLOW_MIN_STEPS or total <= _SLOW_NS * (n - 1):
                    recent.append(elapsed)
                    track.recent_sum_ns = total
                else:
                    note_step_time(track, elapsed)
            checked = guard(est, sole=True)
            if isinstance(checked, str):
                self.fail(track.name, checked, "", step.time)
                continue
            track.means.append(checked[0])
            track.covs.append(checked[1])
            track.ticks.append(step.tick)

    def _stopped(self, track: FilterTrack, exc: BaseException, limit: float | None, of_run: bool,
                 t0: int, cpu0: int, time_s: float) -> None:
        """A step that raised (``exc``): the filter switched off with its one line (a step
        stopped by its time limit is charged its time), or the user's Ctrl-C re-raised."""
        over = self._over(of_run)
        why = failure_of(exc, limit, over)
        if why is None:
            raise exc
        tb = traceback.format_exc()
        if why == over:
            track.step_ns += time.perf_counter_ns() - t0
            if self.run_limit_s is not None:
                track.charged_ns += time.thread_time_ns() - cpu0
        self.fail(track.name, why, tb, time_s)

    def _general(self, track: FilterTrack, f: Filter, step: Step, limit: float | None,
                 of_run: bool) -> object:
        """One step the general way (a step view, or a limit armed around the loop): under
        the :class:`StepWatch`, timed and recorded; the estimate, or ``_FAILED``."""
        watch = self._watch
        watch.seconds = limit
        clock = time.perf_counter_ns
        cpu0 = 0 if self.run_limit_s is None and not self.slow_by_cpu else time.thread_time_ns()
        t0 = clock()
        try:
            with watch:
                est = self._step(track, f, step)
        except BaseException as exc:
            self._stopped(track, exc, limit, of_run, t0, cpu0, step.time)
            return _FAILED
        elapsed = clock() - t0
        track.step_ns += elapsed
        if self.run_limit_s is not None:
            track.charged_ns += time.thread_time_ns() - cpu0
        track.steps += 1
        note_step_time(track, time.thread_time_ns() - cpu0 if self.slow_by_cpu else elapsed)
        return est


#: :meth:`FilterRunner._general`'s answer for a step that failed.
_FAILED = object()


__all__ = [
    "CPU_BACKSTOP_FACTOR", "CPU_BACKSTOP_S", "HEADLESS_STEP_LIMIT_S", "MAX_COV", "MAX_MEAN", "NOT_BUILT",
    "SLOW_MIN_STEPS", "SLOW_STEP_MS", "SLOW_WINDOW", "WINDOW_STEP_LIMIT_S", "FilterExit", "FilterRunner",
    "FilterTimeout", "FilterTrack", "StepWatch", "bounded_track", "call_guarded", "check_estimate",
    "exit_text", "failure_line", "failure_of", "failure_text", "guarded_call", "is_filter_failure",
    "note_step_time", "note_user_interrupt", "one_line", "run_filter_code", "settle_slot", "shape_text",
    "status_line", "step_slot", "time_limit", "user_interrupted", "validate_belief", "validate_estimate",
]
