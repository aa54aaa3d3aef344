"""Feeds each simulation step to any number of filters, side by side on the same data,
and keeps each one's estimate history and cost.

A filter that raises, or returns a non-finite or malformed estimate, is switched off with
a message; the simulation and the other filters go on. That includes an object that does
not implement :class:`~beacon_sim.filters.base.Filter` at all (a student's class is only
duck-typed): its missing method raises on the first step and it is switched off. A filter
that is slow on every step gets a warning (:func:`note_step_time`); :func:`status_line` is
what the window and the terminal show for either.

The one guard: :func:`validate_estimate` and :func:`validate_belief` are what every front
end (``run``, ``eval``, ``grade``, the window) uses to judge what a filter returned, so
nothing a filter returns reaches a metric or the renderer unchecked. Time limits
(``step_limit_s``, ``run_limit_s``) stop a filter stuck in a loop: see :class:`FilterTimeout`.
"""

from __future__ import annotations

import ctypes
import math
import os
import threading
import time
import traceback
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal, TypeVar

import numpy as np

from beacon_sim.core.types import Step
from beacon_sim.filters.base import Belief, Filter, GaussianBelief, GridBelief, ParticleBelief

#: ``FilterTrack.failed`` of a filter that was never built (``None`` given to the runner);
#: the caller usually replaces it with why construction failed.
NOT_BUILT = "not constructed"


#: The longest a step (predict + update + estimate) may take in a headless run and in the
#: window before the filter is stopped [s]: far beyond real time, not a benchmark.
HEADLESS_STEP_LIMIT_S = 10.0
WINDOW_STEP_LIMIT_S = 0.5

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

    @property
    def us_per_step(self) -> float:
        """Mean wall time of predict + update + estimate [microseconds]."""
        return self.step_ns / 1e3 / max(self.steps, 1)


_F8 = np.dtype(float)

#: The largest |mean| entry [m or rad] and covariance entry [m^2 or rad^2] an estimate may
#: hold: beyond them the filter has diverged (and the metrics' products would overflow).
MAX_MEAN = 1e9
MAX_COV = 1e12


def _as_numbers(x: object) -> np.ndarray | None:
    """``x`` as a float array, or None when it is not numbers (strings, objects, complex)."""
    if type(x) is np.ndarray and x.dtype == _F8:  # the usual case, fast
        return x.copy()
    try:
        a = np.asarray(x)
    except Exception:  # an object whose __array__ raises
        return None
    if a.dtype.kind not in "biuf":
        return None
    return a.astype(float, copy=True)


def _type_name(x: object) -> str:
    return "None" if x is None else type(x).__name__


def _not_psd(a: float, b: float, d: float, e: float, f: float, g: float) -> bool:
    """Whether the symmetric 3x3 ``[[a, b, d], [b, e, f], [d, f, g]]`` (finite floats) has
    an eigenvalue below ``-1e-9 * max|entry|``: the matrix plus ``1e-9 max|entry| I`` is
    tested for positive definiteness by its leading principal minors (Sylvester), a few
    float operations instead of an eigen-decomposition. Same verdict as
    ``eigvalsh(c).min() < -1e-9 * scale`` up to rounding."""
    tol = 1e-9 * max(abs(a), abs(b), abs(d), abs(e), abs(f), abs(g), 1e-12)
    a, e, g = a + tol, e + tol, g + tol
    if a <= 0.0:
        return True
    if a * e - b * b <= 0.0:
        return True
    return a * (e * g - f * f) - b * (b * g - f * d) + d * (b * f - e * d) <= 0.0


def validate_estimate(est: object) -> tuple[np.ndarray, np.ndarray] | str:
    """The one guard of what ``estimate()`` returned: ``(mean (3,), cov (3, 3))`` as fresh
    float arrays [m, m, rad], or one line saying why it is unusable (not a pair, not
    numbers, wrong shapes, NaN or infinity, covariance not symmetric, not positive
    semi-definite). Cheap (a few microseconds): it runs on every step of every filter."""
    if isinstance(est, tuple | list) and len(est) == 2:
        fast = _validate_plain(est[0], est[1])
        if fast is not None:
            return fast
    return _validate_any(est)


def _validate_plain(m0: object, c0: object) -> tuple[np.ndarray, np.ndarray] | str | None:
    """:func:`validate_estimate` for the usual case, float64 arrays of the right shapes with
    finite entries, in fewer operations; None for anything else (the full check then runs
    and names what is wrong). A sum of the entries that is finite proves every entry finite
    (a NaN or an infinity would make it NaN or infinite); one that overflows goes the
    long way too, so the verdicts are the same."""
    if not (type(m0) is np.ndarray and type(c0) is np.ndarray and m0.dtype is _F8
            and c0.dtype is _F8 and m0.shape == (3,) and c0.shape == (3, 3)):
        return None
    mean, cov = m0.copy(), c0.copy()
    (a, b, d), (b2, e, f), (d2, f2, g) = cov.tolist()
    x, y, t = mean.tolist()
    if not (math.isfinite(a + b + d + b2 + e + f + d2 + f2 + g) and math.isfinite(x + y + t)):
        return None
    scale = max(abs(a), abs(b), abs(d), abs(b2), abs(e), abs(f), abs(d2), abs(f2), abs(g), 1e-12)
    if scale > MAX_COV or max(abs(x), abs(y), abs(t)) > MAX_MEAN:
        return (f"estimate() returned a mean beyond {MAX_MEAN:g} or a covariance entry over "
                f"{MAX_COV:g} (diverged)")
    if max(abs(b - b2), abs(d - d2), abs(f - f2)) > 1e-6 * scale:
        return "covariance is not symmetric"
    if _not_psd(a, 0.5 * (b + b2), 0.5 * (d + d2), e, 0.5 * (f + f2), g):
        return "covariance is not positive semi-definite"
    return mean, cov


def _validate_any(est: object) -> tuple[np.ndarray, np.ndarray] | str:
    """:func:`validate_estimate` for anything a filter may return."""
    if not isinstance(est, tuple | list) or len(est) != 2:
        return f"estimate() returned {_type_name(est)}, expected a (mean, cov) pair"
    mean, cov = _as_numbers(est[0]), _as_numbers(est[1])
    if mean is None or cov is None:
        return (f"estimate() returned {_type_name(est[0])} and {_type_name(est[1])}, "
                "expected arrays of numbers")
    if mean.shape != (3,) or cov.shape != (3, 3):
        return f"estimate() returned shapes {mean.shape} and {cov.shape}, expected (3,) and (3, 3)"
    c = cov.tolist()
    m = mean.tolist()
    if not all(map(math.isfinite, (*m, *c[0], *c[1], *c[2]))):
        return "estimate() returned NaN or infinity"
    (a, b, d), (b2, e, f), (d2, f2, g) = c
    scale = max(abs(a), abs(b), abs(d), abs(b2), abs(e), abs(f), abs(d2), abs(f2), abs(g), 1e-12)
    if scale > MAX_COV or max(abs(m[0]), abs(m[1]), abs(m[2])) > MAX_MEAN:
        return (f"estimate() returned a mean beyond {MAX_MEAN:g} or a covariance entry over "
                f"{MAX_COV:g} (diverged)")
    if max(abs(b - b2), abs(d - d2), abs(f - f2)) > 1e-6 * scale:
        return "covariance is not symmetric"
    b, d, f = 0.5 * (b + b2), 0.5 * (d + d2), 0.5 * (f + f2)
    if _not_psd(a, b, d, e, f, g):
        return "covariance is not positive semi-definite"
    return mean, cov


def check_estimate(mean: object, cov: object) -> str | None:
    """Why an estimate is unusable (see :func:`validate_estimate`), or None."""
    r = validate_estimate((mean, cov))
    return r if isinstance(r, str) else None


def validate_belief(bel: object) -> Belief | str:
    """The guard of what ``belief()`` returned, for drawing: a belief whose arrays are float,
    finite and of the right shapes, or one line saying why not.

    GaussianBelief: as :func:`validate_estimate`. ParticleBelief: poses (N, 3) [m, m, rad]
    with N >= 1, weights (N,) >= 0 with a positive sum. GridBelief: prob 2-D >= 0 with a
    positive sum, origin two finite numbers [m], cell > 0 [m].
    """
    if isinstance(bel, GaussianBelief):
        r = validate_estimate((bel.mean, bel.cov))
        if isinstance(r, str):
            return "belief(): " + r.replace("estimate() returned", "Gaussian has")
        return GaussianBelief(*r)
    if isinstance(bel, ParticleBelief):
        poses, w = _as_numbers(bel.poses), _as_numbers(bel.weights)
        if poses is None or w is None:
            return "belief(): particle poses or weights are not arrays of numbers"
        if poses.ndim != 2 or poses.shape[1] != 3 or poses.shape[0] < 1 or w.shape != (len(poses),):
            return (f"belief(): particle poses {poses.shape} and weights {w.shape}, "
                    "expected (N, 3) and (N,)")
        if not (np.isfinite(poses).all() and np.isfinite(w).all()):
            return "belief(): particles with NaN or infinity"
        if (w < 0).any() or not w.sum() > 0:
            return "belief(): particle weights must be >= 0 with a positive sum"
        return ParticleBelief(poses, w)
    if isinstance(bel, GridBelief):
        prob = _as_numbers(bel.prob)
        origin = _as_numbers(bel.origin)
        cell = _as_numbers(bel.cell)
        if prob is None or origin is None or cell is None or prob.ndim != 2 or origin.shape != (2,) \
                or cell.shape != () or min(prob.shape) < 1:
            return "belief(): grid needs prob (nx, ny), origin (x, y) [m] and a cell size [m]"
        if not (np.isfinite(prob).all() and np.isfinite(origin).all() and math.isfinite(float(cell))):
            return "belief(): grid with NaN or infinity"
        if (prob < 0).any() or not prob.sum() > 0 or not float(cell) > 0:
            return "belief(): grid probabilities must be >= 0 with a positive sum, cell > 0"
        return GridBelief(prob, (float(origin[0]), float(origin[1])), float(cell))
    return f"belief() returned {_type_name(bel)}, expected a GaussianBelief, ParticleBelief or GridBelief"


class FilterTimeout(BaseException):
    """Raised inside a filter's code when its time is up.

    A :class:`BaseException`, so that a student's ``except Exception`` does not swallow it.
    It is raised by a watchdog thread through ``PyThreadState_SetAsyncExc`` (CPython), which
    works in any thread (the window's main thread, a Dask worker's thread) and costs two
    dictionary operations per step. It interrupts Python code (a ``while True`` loop, a slow
    Python loop); a single long call into C (one huge numpy operation, ``time.sleep``) is
    interrupted when it returns. It is raised again every 0.1 s until the step gives up.
    """


_WD_LOCK = threading.Lock()
_WD_ARMED: dict[int, list[float]] = {}  # thread id -> [deadline (monotonic s), fired 0/1]
_WD_THREAD: threading.Thread | None = None
_WD_POLL_S = 0.02
_WD_REFIRE_S = 0.1


def _after_fork() -> None:
    """A forked worker has no watchdog thread (threads do not survive fork): start afresh."""
    global _WD_THREAD, _WD_LOCK
    _WD_THREAD = None
    _WD_LOCK = threading.Lock()
    _WD_ARMED.clear()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_after_fork)


def _raise_in(thread_id: int, exc: type[BaseException] | None) -> None:
    try:
        ctypes.pythonapi.PyThreadState_SetAsyncExc(ctypes.c_ulong(thread_id),
                                                   ctypes.py_object(exc) if exc else None)
    except (AttributeError, OSError):  # not CPython: no watchdog
        pass


def _watchdog_loop() -> None:
    while True:
        time.sleep(_WD_POLL_S)
        now = time.monotonic()
        with _WD_LOCK:
            for tid, entry in _WD_ARMED.items():
                if now >= entry[0]:
                    _raise_in(tid, FilterTimeout)
                    entry[0] = now + _WD_REFIRE_S
                    entry[1] = 1.0


class time_limit:  # used as ``with time_limit(s):``, like the function it was
    """Raise :class:`FilterTimeout` in the calling thread if the block runs longer than
    ``seconds`` [s] of wall time (None or infinity: no limit). A class rather than a
    generator-based context manager: it runs around every filter step (a few microseconds
    less per step)."""

    __slots__ = ("_armed", "_outer", "_tid", "seconds")

    def __init__(self, seconds: float | None):
        self.seconds = seconds
        self._armed = False

    def __enter__(self) -> time_limit:
        global _WD_THREAD
        seconds = self.seconds
        if seconds is None or not math.isfinite(seconds):
            return self
        tid = threading.get_ident()
        with _WD_LOCK:
            if _WD_THREAD is None:
                _WD_THREAD = threading.Thread(target=_watchdog_loop, name="beacon-sim watchdog",
                                              daemon=True)
                _WD_THREAD.start()
            outer = _WD_ARMED.get(tid)  # a limit around this one (nested): the earlier deadline wins
            deadline = time.monotonic() + max(seconds, 0.0)
            if outer is not None:
                deadline = min(deadline, outer[0])
            _WD_ARMED[tid] = [deadline, 0.0]
        self._tid, self._outer, self._armed = tid, outer, True
        return self

    def __exit__(self, *exc: object) -> Literal[False]:
        if not self._armed:
            return False
        self._armed = False
        tid, outer = self._tid, self._outer
        with _WD_LOCK:
            entry = _WD_ARMED.pop(tid, None)
            if entry is not None and entry[1]:
                _raise_in(tid, None)  # a raise not yet delivered: withdraw it
            if outer is not None:
                _WD_ARMED[tid] = outer
        return False


T = TypeVar("T")

# A Ctrl-C (SIGINT) or SIGTERM from the user, as opposed to a ``KeyboardInterrupt`` or a
# ``SystemExit`` that filter code raised itself: the front ends' signal handlers call
# note_user_interrupt() before raising, and the guard lets only those through.
_USER_INTERRUPT = threading.Event()


def note_user_interrupt() -> None:
    """Record that the user asked to stop (called from a SIGINT / SIGTERM handler)."""
    _USER_INTERRUPT.set()


def user_interrupted() -> bool:
    """Whether the user asked to stop (see :func:`note_user_interrupt`)."""
    return _USER_INTERRUPT.is_set()


class FilterExit(RuntimeError):
    """Filter code raised ``SystemExit`` or ``KeyboardInterrupt`` (not the user's Ctrl-C), or
    ran out of time, where an ordinary exception is expected: a failure of that filter."""


def is_filter_failure(exc: BaseException) -> bool:
    """Whether ``exc``, raised inside filter code, is that filter's failure (everything but
    the user's own Ctrl-C / SIGTERM and the interpreter's GeneratorExit)."""
    if isinstance(exc, KeyboardInterrupt):
        return not user_interrupted()
    return isinstance(exc, Exception | SystemExit | FilterTimeout)


def exit_text(exc: BaseException) -> str:
    """One line for a ``SystemExit`` / ``KeyboardInterrupt`` raised by filter code."""
    if isinstance(exc, SystemExit):
        return f"SystemExit({exc.code!r}) raised by the filter"
    return f"{type(exc).__name__} raised by the filter"


def run_filter_code(fn: Callable[[], T], seconds: float | None, what: str) -> T:
    """``fn()`` (a filter's ``__init__``, ``reset``, import...) under :func:`time_limit`, with
    ``SystemExit``, a ``KeyboardInterrupt`` that is not the user's and a time-out turned into
    :class:`FilterExit`, so that every ``except Exception`` handles them as the filter's failure."""
    try:
        with time_limit(seconds):
            return fn()
    except FilterTimeout:
        raise FilterExit(f"{what}: time limit: stopped after {seconds:g} s") from None
    except (SystemExit, KeyboardInterrupt) as exc:
        if not is_filter_failure(exc):
            raise
        raise FilterExit(f"{what}: {exit_text(exc)}") from exc


def guarded_call(fn: Callable[[], T], seconds: float | None) -> tuple[T | None, str | None, str]:
    """``fn()`` under :func:`time_limit`: (its value, None, "") or (None, why it failed in one
    line, the traceback). The user's own Ctrl-C goes through."""
    try:
        with time_limit(seconds):
            return fn(), None, ""
    except FilterTimeout:
        return None, f"time limit: stopped after {seconds:g} s", traceback.format_exc()
    except Exception as exc:
        return None, one_line(exc), traceback.format_exc()
    except (SystemExit, KeyboardInterrupt) as exc:
        if not is_filter_failure(exc):
            raise
        return None, exit_text(exc), traceback.format_exc()


def one_line(exc: BaseException) -> str:
    """``Type: message`` on one line."""
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__


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
    """

    #: Filters (by name) whose estimate after predict and before update is copied, each
    #: step, into ``priors[name]`` as (mean (3,), cov (3, 3)): the window's step view.
    #: Empty (the default): no extra call; the filters' results are the same either way.
    keep_prior: frozenset[str] = frozenset()
    priors: dict[str, tuple[np.ndarray, np.ndarray]]

    def __init__(self, filters: Mapping[str, Filter | None], step_limit_s: float | None = None,
                 run_limit_s: float | None = None, keep: int | None = None):
        self.keep = keep
        self.tracks = {name: bounded_track(name, f, keep, failed=None if f is not None else NOT_BUILT)
                       for name, f in filters.items()}
        self.step_limit_s = step_limit_s
        self.run_limit_s = run_limit_s

    def fail(self, name: str, reason: str, tb: str = "", time_s: float | None = None) -> None:
        """Switch ``name`` off with ``reason`` (one line), at simulated time ``time_s`` [s]."""
        track = self.tracks[name]
        if track.failed and track.failed != NOT_BUILT:
            return
        track.failed, track.traceback, track.failed_time_s = reason, tb, time_s

    def _limit(self, track: FilterTrack) -> tuple[float | None, str]:
        """The time this track's next step may take [s] and the message when it is over
        (the step limit, or what is left of the run limit, whichever is shorter)."""
        step, run = self.step_limit_s, self.run_limit_s
        if run is not None:
            left = run - track.step_ns / 1e9
            if step is None or left < step:
                return left, f"time limit: over {run:g} s of filter time in the run"
        if step is None:
            return None, ""
        return step, f"time limit: a step took over {step:g} s"

    def feed(self, step: Step) -> None:
        """Predict with the step's command, update with its measurements, record."""
        for track in self.tracks.values():
            f = track.filter
            if track.failed or f is None:
                continue
            limit, over = self._limit(track)
            t0 = time.perf_counter_ns()
            try:
                try:
                    with time_limit(limit):
                        f.predict(step.control, step.dt)
                        if track.name in self.keep_prior:  # the step view: the belief after predict
                            prior = validate_estimate(f.estimate())  # the one guard
                            if isinstance(prior, str):
                                raise ValueError(f"after predict: {prior}")
                            self.priors[track.name] = prior
                        f.update(step.measurements)
                        est: Any = f.estimate()
                finally:
                    elapsed = time.perf_counter_ns() - t0
            except FilterTimeout:
                track.step_ns += elapsed
                self.fail(track.name, over, traceback.format_exc(), step.time)
                continue
            except Exception as exc:
                self.fail(track.name, one_line(exc), traceback.format_exc(), step.time)
                continue
            except (SystemExit, KeyboardInterrupt) as exc:  # raised by the filter's code
                if not is_filter_failure(exc):
                    raise  # the user's Ctrl-C: stop the program
                self.fail(track.name, exit_text(exc), traceback.format_exc(), step.time)
                continue
            track.step_ns += elapsed
            track.steps += 1
            note_step_time(track, elapsed)
            checked = validate_estimate(est)
            if isinstance(checked, str):
                self.fail(track.name, checked, "", step.time)
                continue
            track.means.append(checked[0])
            track.covs.append(checked[1])
            track.ticks.append(step.tick)
