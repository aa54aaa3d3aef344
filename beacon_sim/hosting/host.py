"""The host: the one place that calls a filter's code and turns what can go wrong into one
line (the guarded-call ladder), used by the runner, the Monte Carlo runs, the conformance
checks and the isolated child alike.

A filter's call ends in one of four ways: it returns; it raises an ``Exception`` (``Type:
message``); it raises ``SystemExit`` or a ``KeyboardInterrupt`` that is not the user's own
(``SystemExit(3) raised by the filter``); it runs out of time (``time limit: ...``, see
:mod:`beacon_sim.hosting.watchdog`). The user's own Ctrl-C always goes through.

The seam: whatever satisfies :class:`~beacon_sim.filters.base.Filter` can be hosted, an
object in this process or the proxy of a filter in a child process
(:mod:`beacon_sim.hosting.isolated`).
"""

from __future__ import annotations

import traceback
from collections.abc import Callable
from typing import TypeVar

from beacon_sim.hosting.watchdog import (
    FilterExit,
    FilterTimeout,
    exit_text,
    is_filter_failure,
    one_line,
    time_limit,
)

T = TypeVar("T")


def failure_of(exc: BaseException, seconds: float | None, over: str | None = None) -> str | None:
    """The one line for ``exc`` raised by filter code under a limit of ``seconds`` [s]
    (``over``: the time-out's text), or None when it is not the filter's failure (the
    user's Ctrl-C, GeneratorExit): then the caller re-raises it."""
    if isinstance(exc, FilterTimeout):
        return over or f"time limit: stopped after {seconds:g} s"
    if isinstance(exc, Exception):
        return one_line(exc)
    if isinstance(exc, SystemExit | KeyboardInterrupt) and is_filter_failure(exc):
        return exit_text(exc)
    return None


def call_guarded(fn: Callable[[], T], seconds: float | None, *, cpu: bool = False,
                 over: str | None = None) -> tuple[T | None, str | None, str]:
    """``fn()`` under :class:`~beacon_sim.hosting.watchdog.time_limit` (``cpu``: CPU time):
    (its value, None, "") or (None, why it failed in one line, the traceback)."""
    try:
        with time_limit(seconds, cpu):
            return fn(), None, ""
    except BaseException as exc:
        why = failure_of(exc, seconds, over)
        if why is None:
            raise
        return None, why, traceback.format_exc()


def guarded_call(fn: Callable[[], T], seconds: float | None) -> tuple[T | None, str | None, str]:
    """``fn()`` under a wall-time limit: (its value, None, "") or (None, why it failed in one
    line, the traceback). The user's own Ctrl-C goes through."""
    return call_guarded(fn, seconds)


def run_filter_code(fn: Callable[[], T], seconds: float | None, what: str, *, cpu: bool = False) -> T:
    """``fn()`` (a filter's ``__init__``, ``reset``, import...) under a time limit, with
    ``SystemExit``, a ``KeyboardInterrupt`` that is not the user's and a time-out turned into
    :class:`FilterExit`, so that every ``except Exception`` handles them as the filter's
    failure; an ordinary exception goes through as it is."""
    try:
        with time_limit(seconds, cpu):
            return fn()
    except (FilterTimeout, SystemExit, KeyboardInterrupt) as exc:
        why = failure_of(exc, seconds)
        if why is None:
            raise
        raise FilterExit(f"{what}: {why}") from (None if isinstance(exc, FilterTimeout) else exc)


__all__ = ["call_guarded", "failure_of", "guarded_call", "run_filter_code"]
