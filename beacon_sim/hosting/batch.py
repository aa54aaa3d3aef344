"""The filters of one batch of runs in a student's process (one per seed, and the probes:
nothing here tells them apart), each built from its own fresh copy of the student's file,
with its own CPU-time budget, failure and cost (:class:`Batch`); and the step of one filter
(:func:`timed_step`, :func:`map_of`, :func:`joint_entry`). Served by
:mod:`beacon_sim.hosting.child` in the child, and by
:class:`~beacon_sim.hosting.feed.LocalChild` in the grader's own process.
"""

from __future__ import annotations

import time
from typing import Any


def timed_step(f: Any, control: Any, dt: float, measurements: Any, want_prior: bool,
               clock: Any = time.perf_counter_ns) -> tuple[int, Any, Any]:
    """One step of a hosted filter: predict, the estimate after predict when ``want_prior``
    (the step view), update, estimate. Returns (the step's time [ns] without the prior's
    read, the prior or None, the estimate), unchecked."""
    t0 = clock()
    f.predict(control, dt)
    t1 = clock()
    prior = f.estimate() if want_prior else None
    t2 = clock()
    f.update(measurements)
    est = f.estimate()
    return (t1 - t0) + (clock() - t2), prior, est


def map_of(f: Any) -> bytes | str | None:
    """The map block of a SLAM filter (one with ``landmarks()``) after its step, or the
    one-line fault of what ``landmarks()`` returned; None for a filter without a map (no
    cost). Called under the step's time limit: a ``landmarks()`` that loops is stopped as a
    step that loops; one that raises raises (the step fails with its one line)."""
    lm = getattr(f, "landmarks", None)
    if not callable(lm):
        return None
    from beacon_sim.hosting.watchdog import one_line
    from beacon_sim.hosting.wire import encode_landmarks

    try:
        got = lm()
    except Exception as exc:  # a time-out (not an Exception) ends the step as it would
        return f"landmarks() raised {one_line(exc)}"
    return encode_landmarks(got)


def joint_entry(f: Any, watch: Any, seconds: float | None) -> bytes:
    """The reply entry of a filter's final ``joint()`` (mean, cov, IDs): a JOINT entry of
    three float arrays, or OK when there is none to report (no ``joint()``, it raised or
    ran over ``seconds`` [s] of CPU time under ``watch``, or more than
    :data:`~beacon_sim.hosting.wire.MAX_JOINT_LANDMARKS` landmarks)."""
    import numpy as np

    from beacon_sim.hosting.wire import MAX_JOINT_LANDMARKS, OK, encode_joint, reply

    joint = getattr(f, "joint", None)
    if not callable(joint):
        return reply(OK)
    try:
        watch.seconds = seconds
        with watch:
            mean, cov, ids = joint()
            arrays = [np.asarray(mean, dtype=float), np.asarray(cov, dtype=float),
                      np.asarray(ids, dtype=float)]
    except BaseException:  # a joint() that fails is not reported (the run is scored already)
        return reply(OK)
    if arrays[2].size > MAX_JOINT_LANDMARKS or arrays[1].size > (3 + 2 * MAX_JOINT_LANDMARKS) ** 2:
        return reply(OK)
    return encode_joint(*arrays)


class Batch:
    """The filters of one batch of runs (one per seed, and the probes: nothing here tells
    them apart), each from its own fresh copy of the student's file (``fresh_class()``),
    with its own CPU-time budget, failure and cost; a failed one is switched off and the
    others go on. Also what :class:`~beacon_sim.hosting.feed.LocalChild` runs in process."""

    def __init__(self, fresh_class: Any, builds: list[tuple[Any, Any, str]], run_limit_s: float | None,
                 all_threads: bool = False):
        from beacon_sim.hosting.loading import build_from_context
        from beacon_sim.hosting.processes import children_usage
        from beacon_sim.hosting.watchdog import StepWatch
        from beacon_sim.hosting.wire import OK, reply, reply_multi

        self.limit_s = run_limit_s
        #: In a student's own process (hosted): a run is charged the CPU time of every
        #: thread of the process while its filter's code runs (a helper thread's work counts),
        #: and the CPU the other threads use between exchanges, shared among the runs still
        #: going; in the grader's process (LocalChild) its own thread's only.
        self.cpu = time.process_time_ns if all_threads else time.thread_time_ns
        self.all_threads = all_threads
        self._mark: tuple[int, int] | None = None
        self._children = children_usage() if all_threads else None
        self.over = (None if run_limit_s is None
                     else f"time limit: over {run_limit_s:g} s of filter time in the run")
        self.watch = StepWatch(cpu=True)
        self.filters: list[Any] = []
        self.used = [0] * len(builds)  # CPU time of each run's filter code [ns]
        entries = []
        for ctx, initial, spec in builds:  # the import's and the build's own limits, as
            try:                           # alone (CPU time); the run's budget counts the steps
                flt = build_from_context(fresh_class(), ctx, initial, spec, cpu=True)
            except BaseException as exc:
                self.filters.append(None)
                entries.append(self._fail(exc, "construction failed: "))
                continue
            self.filters.append(flt)
            entries.append(reply(OK))
        self.built = reply_multi(entries)
        self.mark()

    def mark(self) -> None:
        """The end of an exchange: from here, CPU the process uses outside the main thread
        (a helper thread working between ticks) is charged at the next exchange."""
        if self.all_threads:
            self._mark = (time.process_time_ns(), time.thread_time_ns())

    def processes_started(self) -> str | None:
        """Whether the student's code started a process (one still running, below this one:
        the child is their subreaper, so a double fork stays below it; or one that ran and
        was reaped): its CPU time and memory cannot be counted with the student's at the
        process level, so it is not allowed. Such processes are killed."""
        from beacon_sim.hosting.processes import (
            PROCESS_NOT_ALLOWED,
            children_usage,
            has_children,
            stop_descendants,
        )

        if not self.all_threads:
            return None
        ran = children_usage() != self._children
        if not ran and not has_children():  # the every-tick case: nothing below this process
            return None
        if stop_descendants() or ran or children_usage() != self._children:
            self._children = children_usage()
            return PROCESS_NOT_ALLOWED
        return None

    def charge_between(self) -> None:
        """Charge the CPU time the other threads used since the last exchange to the runs
        still going, in equal shares (each run's budget its own: nothing says which run's
        filter started the thread)."""
        if self._mark is None:
            return
        other = (time.process_time_ns() - self._mark[0]) - (time.thread_time_ns() - self._mark[1])
        live = [k for k, f in enumerate(self.filters) if f is not None]
        if other > 0 and live:
            for k in live:
                self.used[k] += other // len(live)

    def switch_off(self, k: int) -> None:
        """Run k failed: its filter is dropped."""
        self.filters[k] = None

    def _timed(self, k: int, fn: Any) -> Any:
        """``fn()`` of run k's filter under what is left of its run's CPU-time budget,
        charged to it (the estimate after reset, the final belief)."""
        limit = self.limit_s
        c0 = self.cpu()
        try:
            self.watch.seconds = None if limit is None else limit - self.used[k] / 1e9
            with self.watch:
                return fn()
        finally:
            self.used[k] += self.cpu() - c0

    def firsts(self, slots: list[int]) -> bytes:
        from beacon_sim.hosting.guard import estimate_arrays
        from beacon_sim.hosting.wire import reply_estimate, reply_multi

        entries = []
        for k in slots:
            f = self.filters[k] if 0 <= k < len(self.filters) else None
            if f is None:
                raise ValueError(f"the estimate after reset of run {k}, which is not going")
            try:
                est = estimate_arrays(self._timed(k, f.estimate))
            except BaseException as exc:  # reported; the run goes on (its steps decide)
                entries.append(self._fail(exc))
                continue
            entries.append(self._fail_text(est) if isinstance(est, str) else reply_estimate(0, None, est))
        return reply_multi(entries)

    def beliefs(self, slots: list[int]) -> bytes:
        from beacon_sim.filters.base import GaussianBelief, GridBelief, ParticleBelief
        from beacon_sim.hosting.wire import OK, reply, reply_multi

        entries = []
        for k in slots:
            f = self.filters[k] if 0 <= k < len(self.filters) else None
            if f is None:
                raise ValueError(f"the belief of run {k}, which is not going")
            try:
                b = self._timed(k, f.belief)
            except BaseException as exc:
                entries.append(self._fail(exc))
                continue
            entries.append(reply(OK) if isinstance(b, GaussianBelief | ParticleBelief | GridBelief) else
                           self._fail_text(f"belief() returned {type(b).__name__}, expected a "
                                           "GaussianBelief, ParticleBelief or GridBelief"))
        return reply_multi(entries)

    def _fail(self, exc: BaseException, prefix: str = "") -> bytes:
        import traceback

        from beacon_sim.hosting.host import failure_of
        from beacon_sim.hosting.wire import FAIL, reply_json

        why = failure_of(exc, self.limit_s, self.over) or f"{type(exc).__name__} raised by the filter"
        return reply_json(FAIL, {"why": prefix + why, "tb": traceback.format_exc()})

    def _fail_text(self, why: str) -> bytes:
        from beacon_sim.hosting.wire import FAIL, reply_json

        return reply_json(FAIL, {"why": why, "tb": ""})

    def joints(self, slots: list[int]) -> bytes:
        from beacon_sim.hosting.wire import reply_multi

        entries = []
        for k in slots:
            f = self.filters[k] if 0 <= k < len(self.filters) else None
            left = None if self.limit_s is None else self.limit_s - self.used[k] / 1e9
            entries.append(joint_entry(f, self.watch, left))
        return reply_multi(entries)

    def step(self, slots: list[int], bodies: list[bytes]) -> bytes:
        import pickle

        from beacon_sim.hosting.guard import estimate_arrays
        from beacon_sim.hosting.wire import reply_estimate, reply_multi

        clock, cpu, watch, limit = time.perf_counter_ns, self.cpu, self.watch, self.limit_s
        self.charge_between()
        entries = []
        for k, body in zip(slots, bodies, strict=True):
            f = self.filters[k] if 0 <= k < len(self.filters) else None
            if f is None:
                raise ValueError(f"a batch tick for run {k}, which is not going")
            _op, control, dt, measurements, want_prior = pickle.loads(body)
            c0 = cpu()
            try:
                watch.seconds = None if limit is None else limit - self.used[k] / 1e9
                with watch:
                    wall, prior, est = timed_step(f, control, dt, measurements, want_prior, clock)
                    block = map_of(f)
            except BaseException as exc:
                self.switch_off(k)
                entries.append(self._fail(exc))
                continue
            finally:
                self.used[k] += cpu() - c0
            post = estimate_arrays(est)
            pri: Any = None
            if not isinstance(post, str) and want_prior:
                pri = estimate_arrays(prior)
                if isinstance(pri, str):
                    post = "after predict: " + pri
            if isinstance(post, str):
                self.switch_off(k)
                entries.append(self._fail_text(post))
                continue
            if limit is not None and self.used[k] > limit * 1e9:
                self.switch_off(k)
                entries.append(self._fail_text(self.over or "time limit"))
                continue
            if isinstance(block, str):
                self.switch_off(k)
                entries.append(self._fail_text(block))
                continue
            entries.append(reply_estimate(wall, pri, post, block))
        started = self.processes_started()
        if started:  # every run still going fails: nothing says which run's filter did it
            entries = [self._fail_text(started) if self.filters[k] is not None else e
                       for k, e in zip(slots, entries, strict=True)]
            for k in slots:
                self.switch_off(k)
        out = reply_multi(entries)
        self.mark()
        return out


__all__ = ["Batch", "joint_entry", "map_of", "timed_step"]
