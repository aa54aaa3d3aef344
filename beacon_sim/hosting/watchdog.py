"""The watchdog: time limits on filter code, and the user's own interrupts told apart from
a filter's.

:class:`time_limit` raises :class:`FilterTimeout` in the thread that runs a filter when
its time is up: wall time (the window, which must keep up with real time) or CPU time of
that thread (headless runs and grading: a verdict that does not depend on how loaded the
machine is), with a wall-time backstop for code that sleeps. :func:`note_user_interrupt`
records a Ctrl-C or SIGTERM from the user, so that :func:`is_filter_failure` lets only
those through and treats a ``KeyboardInterrupt`` or ``SystemExit`` raised by filter code
as that filter's failure.
"""

from __future__ import annotations

import ctypes
import math
import os
import threading
import time
from typing import Literal


class FilterTimeout(BaseException):
    """Raised inside a filter's code when its time is up.

    A :class:`BaseException`, so that a student's ``except Exception`` does not swallow it.
    It is raised by a watchdog thread through ``PyThreadState_SetAsyncExc`` (CPython), which
    works in any thread (the window's main thread, a Dask worker's thread) and costs two
    dictionary operations per step. It interrupts Python code (a ``while True`` loop, a slow
    Python loop); a single long call into C (one huge numpy operation, ``time.sleep``) is
    interrupted when it returns. It is raised again every 0.1 s until the step gives up.
    """


#: A CPU-time limit's wall-time backstop: code that sleeps (uses no CPU) is stopped after
#: ``CPU_BACKSTOP_FACTOR * seconds + CPU_BACKSTOP_S`` of wall time.
CPU_BACKSTOP_FACTOR = 5.0
CPU_BACKSTOP_S = 10.0

_WD_LOCK = threading.Lock()
# thread id -> [wall deadline (monotonic s), fired 0/1, CPU limit [s] or -1, CPU clock id or
# -1, the thread's CPU time when the watchdog first saw the entry [s] or -1]
_WD_ARMED: dict[int, list[float]] = {}
_WD_THREAD: threading.Thread | None = None
# thread id -> that thread's own entry for :class:`StepWatch`, kept in ``_WD_ARMED`` between
# steps with the deadline at infinity (not armed)
_WD_SLOTS: dict[int, list[float]] = {}
_WD_POLL_S = 0.02
_INF = math.inf
_get_ident = threading.get_ident
_monotonic = time.monotonic
_WD_REFIRE_S = 0.1


def _after_fork() -> None:
    """A forked worker has no watchdog thread (threads do not survive fork): start afresh."""
    global _WD_THREAD, _WD_LOCK
    _WD_THREAD = None
    _WD_LOCK = threading.Lock()
    _WD_ARMED.clear()
    _WD_SLOTS.clear()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_after_fork)


def cpu_clock_available() -> bool:
    """Whether another thread's CPU time can be read here (Linux and most Unixes)."""
    try:
        time.clock_gettime(time.pthread_getcpuclockid(threading.get_ident()))
        return True
    except (AttributeError, OSError):
        return False


_CPU_OK = cpu_clock_available()


def _raise_in(thread_id: int, exc: type[BaseException] | None) -> None:
    try:
        ctypes.pythonapi.PyThreadState_SetAsyncExc(ctypes.c_ulong(thread_id),
                                                   ctypes.py_object(exc) if exc else None)
    except (AttributeError, OSError):  # not CPython: no watchdog
        pass


def _cpu_over(tid: int, entry: list[float]) -> bool:
    """Whether the thread ``tid`` has used its CPU allowance since the watchdog first saw
    ``entry`` (the CPU spent before that, under one poll period, is not counted)."""
    if entry[2] < 0:
        return False
    try:
        if entry[3] < 0:
            entry[3] = float(time.pthread_getcpuclockid(tid))
        now = time.clock_gettime(int(entry[3]))
    except (AttributeError, OSError):  # the thread is gone, or no CPU clock
        return False
    if entry[4] < 0:
        entry[4] = now
        return False
    return now - entry[4] >= entry[2]


def _start_watchdog() -> None:
    """Start the watchdog thread if it is not running (call with ``_WD_LOCK`` held)."""
    global _WD_THREAD
    if _WD_THREAD is None:
        _WD_THREAD = threading.Thread(target=_watchdog_loop, name="beacon-sim watchdog", daemon=True)
        _WD_THREAD.start()


def _watchdog_loop() -> None:
    while True:
        time.sleep(_WD_POLL_S)
        now = time.monotonic()
        with _WD_LOCK:
            for tid, entry in _WD_ARMED.items():
                deadline = entry[0]
                if now >= deadline or _cpu_over(tid, entry):
                    # "fired" first, then a second look: a StepWatch step ends without the lock
                    # (deadline to infinity, then it reads "fired"); one that ended before this
                    # look is not stopped, one that ends after it sees "fired" and waits here
                    entry[1] = 1.0
                    if entry[0] is not deadline:  # the step ended (or the next began) meanwhile
                        entry[1] = 0.0
                        continue
                    _raise_in(tid, FilterTimeout)
                    entry[0] = now + _WD_REFIRE_S
                    entry[2] = -1.0  # from now on re-fired by wall time, every 0.1 s


class time_limit:  # used as ``with time_limit(s):``, like the function it was
    """Raise :class:`FilterTimeout` in the calling thread if the block runs longer than
    ``seconds`` [s] (None or infinity: no limit). ``cpu=False``: wall time. ``cpu=True``:
    the thread's CPU time where it can be measured (else wall time), with a wall-time
    backstop (``CPU_BACKSTOP_FACTOR * seconds + CPU_BACKSTOP_S``) for code that sleeps
    (``backstop=False``: none; only where something else watches the wall clock). A
    class rather than a generator-based context manager: it runs around every filter step
    (a few microseconds less per step)."""

    __slots__ = ("_armed", "_outer", "_tid", "backstop", "cpu", "seconds")

    def __init__(self, seconds: float | None, cpu: bool = False, backstop: bool = True):
        self.seconds = seconds
        self.cpu = cpu and _CPU_OK
        self.backstop = backstop or not self.cpu
        self._armed = False

    def __enter__(self) -> time_limit:
        seconds = self.seconds
        if seconds is None or not math.isfinite(seconds):
            return self
        seconds = max(seconds, 0.0)
        tid = threading.get_ident()
        wall = seconds * CPU_BACKSTOP_FACTOR + CPU_BACKSTOP_S if self.cpu else seconds
        if not self.backstop:  # CPU time only (the isolated child: its grader keeps the wall clock)
            wall = math.inf
        with _WD_LOCK:
            _start_watchdog()
            outer = _WD_ARMED.get(tid)  # a limit around this one (nested): the earlier deadline wins
            deadline = time.monotonic() + wall
            if outer is not None:
                deadline = min(deadline, outer[0])
            _WD_ARMED[tid] = [deadline, 0.0, seconds if self.cpu else -1.0, -1.0, -1.0]
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


class StepWatch:
    """:class:`time_limit` for a loop of many short steps (the runner's filter steps), the
    same limits and verdicts at a fraction of the cost: one object reused for every step
    (set ``seconds``, then ``with watch:``), and the thread's entry in the watchdog's table
    kept between steps with its deadline at infinity, so arming a step is a clock read and
    a few writes (no allocation, no lock). Ending one takes no lock either unless the
    watchdog fired: the step sets the deadline to infinity, then reads the "fired" mark; the
    watchdog sets that mark before it raises and then looks at the deadline again, so either
    it sees the step over and does not raise, or the step sees the mark and settles under
    the lock (:func:`settle_slot`: a raise not yet delivered is withdrawn).

    Where another limit is already armed in the thread (a :class:`time_limit` around the
    loop, or a StepWatch inside a step), it falls back to :class:`time_limit`, which nests.
    """

    __slots__ = ("_armed", "_fallback", "cpu", "seconds")

    def __init__(self, cpu: bool = False):
        self.cpu = cpu and _CPU_OK
        self.seconds: float | None = None
        self._armed: list[float] | None = None
        self._fallback: time_limit | None = None

    def __enter__(self) -> StepWatch:
        seconds = self.seconds
        if seconds is None or not -_INF < seconds < _INF:  # no limit (None, infinite or NaN)
            return self
        tid = _get_ident()
        entry = _WD_SLOTS.get(tid)
        if entry is None or _WD_ARMED.get(tid) is not entry or entry[0] != math.inf:
            entry = _own_slot(tid)
            if entry is None:  # another limit is armed here: the general way, which nests
                self._fallback = time_limit(seconds, self.cpu)
                self._fallback.__enter__()
                return self
        if seconds < 0.0:
            seconds = 0.0
        if self.cpu:  # the watchdog takes the thread's CPU clock and time when it first sees these
            entry[3] = -1.0
            entry[4] = -1.0
            entry[2] = seconds
            entry[0] = _monotonic() + seconds * CPU_BACKSTOP_FACTOR + CPU_BACKSTOP_S
        else:
            entry[0] = _monotonic() + seconds
        self._armed = entry
        return self

    def __exit__(self, *exc: object) -> Literal[False]:
        entry = self._armed
        if entry is None:
            fallback = self._fallback
            if fallback is not None:
                self._fallback = None
                fallback.__exit__(*exc)
            return False
        self._armed = None
        entry[0] = _INF  # idle, without the lock: the watchdog looks again after "fired"
        entry[2] = -1.0
        if entry[1]:  # it fired (or is firing): settle under the lock
            settle_slot(entry)
        return False


def settle_slot(entry: list[float]) -> None:
    """End a :class:`StepWatch` step whose watchdog entry ``entry`` fired (or may have):
    under the lock, the entry idle again and a raise not yet delivered withdrawn. Also what
    a step that was stopped (or failed) calls, so that nothing is re-fired after it."""
    with _WD_LOCK:
        entry[0] = _INF
        entry[2] = -1.0
        if entry[1]:
            entry[1] = 0.0
            _raise_in(_get_ident(), None)  # a raise not yet delivered: withdraw it


def step_slot(tid: int) -> list[float] | None:
    """Thread ``tid``'s idle :class:`StepWatch` entry, to arm in place (``entry[0]``: the
    wall deadline; under a CPU limit also ``entry[2..4]``, see ``StepWatch.__enter__``) and
    end as ``StepWatch.__exit__`` does (deadline to infinity, CPU limit off, then
    :func:`settle_slot` if ``entry[1]``, "fired", is set); None when another limit is armed in the thread
    (then use a StepWatch, which nests)."""
    entry = _WD_SLOTS.get(tid)
    if entry is None or _WD_ARMED.get(tid) is not entry or entry[0] != _INF:
        entry = _own_slot(tid)
    return entry


def _own_slot(tid: int) -> list[float] | None:
    """The thread's :class:`StepWatch` entry, (re)placed in the watchdog's table; None when
    another limit is armed in the thread."""
    with _WD_LOCK:
        _start_watchdog()
        current = _WD_ARMED.get(tid)
        slot = _WD_SLOTS.get(tid)
        if current is not None and (current is not slot or current[0] != math.inf):
            return None
        if slot is None:
            slot = _WD_SLOTS[tid] = [math.inf, 0.0, -1.0, -1.0, -1.0]
        _WD_ARMED[tid] = slot
        return slot


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


class FilterFailed(Exception):
    """A filter's failure already put in one line elsewhere (by the child process that
    hosts it, :mod:`beacon_sim.hosting.isolated`): :func:`one_line` gives the line as it is."""


def one_line(exc: BaseException) -> str:
    """``Type: message`` on one line (a :class:`FilterFailed`: its message alone)."""
    text = str(exc).strip().splitlines()
    if isinstance(exc, FilterFailed):
        return text[0] if text else "the filter failed"
    return f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__


def failure_line(exc: BaseException) -> str:
    """One line for whatever filter code raised (``SystemExit`` and ``KeyboardInterrupt``
    included)."""
    return exit_text(exc) if isinstance(exc, SystemExit | KeyboardInterrupt) else one_line(exc)


__all__ = ["FilterExit", "FilterFailed", "FilterTimeout", "StepWatch", "cpu_clock_available", "exit_text",
           "failure_line", "is_filter_failure", "note_user_interrupt", "one_line", "settle_slot", "step_slot",
           "time_limit", "user_interrupted"]
