"""A thread that runs a live session's filter ticks, one after another, beside the window's
drawing (:class:`FilterWorker`).

The window's main thread steps the simulation (the truth, the readings) and hands each tick's
filter work to the worker as a job; it never waits for one. The jobs run in the order given,
each to its end, so the filters see exactly the inputs a synchronous run gives them. numpy
releases the interpreter lock in its heavy kernels, so a 50,000-particle filter's tick and the
drawing share the two cores instead of taking turns.

The worker knows nothing about sessions: a job is a callable ``job(last)`` whose result is
kept until :meth:`FilterWorker.results` takes it (``last``: no other job waits behind it, so
the job may spend time on what only the newest tick needs, the pictures to draw). A job that
raises stops the worker: the exception is raised again in the caller's thread by the next
:meth:`~FilterWorker.results` or :meth:`~FilterWorker.submit` (a filter's own failures never
get this far: the runner's guard and watchdog switch the filter off inside the job).
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from beacon_sim.core.team import TeamStep
from beacon_sim.runs.filter_snapshot import Drawing, FilterTick

if TYPE_CHECKING:
    from beacon_sim.hosting.team_runner import TeamRunner

_STOP = object()


class FilterWorker:
    """One thread running jobs in order (see the module docstring).

    ``busy`` is True from :meth:`submit` until that job's result is ready; while it is
    False no job runs, so the caller may touch what the jobs touch (the filters).
    """

    def __init__(self, name: str = "beacon-sim filters") -> None:
        self._jobs: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self._cond = threading.Condition()
        self._done: list[Any] = []
        self._submitted = 0
        self._finished = 0
        self._error: BaseException | None = None
        self.cpu_s = 0.0  # the jobs' CPU time so far, of this thread [s]
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    @property
    def busy(self) -> bool:
        """Whether a job submitted has not finished yet."""
        return self._finished < self._submitted

    @property
    def alive(self) -> bool:
        return self._thread.is_alive()

    def on_thread(self) -> bool:
        """Whether the caller runs on this worker's thread (inside a job)."""
        return threading.get_ident() == self._thread.ident

    def submit(self, job: Callable[[bool], Any]) -> None:
        """Queue ``job`` after the others (raises a job's earlier exception, if any)."""
        self._raise()
        if not self._thread.is_alive():
            raise RuntimeError("the filter worker was stopped")
        with self._cond:
            self._submitted += 1
        self._jobs.put(job)

    def results(self) -> list[Any]:
        """The results of the jobs finished since the last call, in order."""
        with self._cond:
            out, self._done = self._done, []
        self._raise()
        return out

    def wait(self, timeout: float | None = None) -> bool:
        """Wait until no job is left (at most ``timeout`` [s]); whether that happened."""
        end = None if timeout is None else time.monotonic() + timeout
        with self._cond:
            while self.busy:
                left = None if end is None else end - time.monotonic()
                if left is not None and left <= 0:
                    return False
                self._cond.wait(left)
        return True

    def stop(self, timeout: float | None = None) -> bool:
        """Finish the jobs queued, then end the thread (at most ``timeout`` [s] in all);
        whether it ended. Idempotent; the results not taken stay for :meth:`results`."""
        if self._thread.is_alive():
            self._jobs.put(_STOP)
            self._thread.join(timeout)
        return not self._thread.is_alive()

    def _raise(self) -> None:
        if self._error is not None:
            error, self._error = self._error, None
            raise error

    def _run(self) -> None:
        clock = time.thread_time
        while True:
            job = self._jobs.get()
            if job is _STOP:
                return
            if self._error is not None:  # a job failed: the rest are dropped
                out = None
            else:
                c0 = clock()
                try:
                    out = job(self._jobs.empty())
                except BaseException as exc:  # raised again in the caller's thread
                    self._error = exc
                    out = None
                self.cpu_s += clock() - c0
            with self._cond:
                if out is not None:
                    self._done.append(out)
                self._finished += 1
                self._cond.notify_all()


class WorkerTicks:
    """A live session's ticks with its filters on a :class:`FilterWorker` (``runs/live.Session``
    is made of this): start and stop the worker, hand it each tick's filter work, show the
    ticks it finished. Without a worker (the default) every tick runs its filters at once."""

    # What this reads and changes, all set up by the session (live.Session).
    worker: FilterWorker | None
    recorder: Any
    filters_run: TeamRunner
    names: list[str]
    sim: Any
    _state: FilterTick | None
    _waiting: list[tuple[TeamStep, list[dict], FilterTick]]
    _shown_at: tuple[int, float, np.ndarray]
    _beliefs: dict
    _fail_time: float

    def _filter_tick(self, tick: int, drawing: bool = False) -> FilterTick:
        raise NotImplementedError

    def _sync_status(self, name: str) -> None:
        raise NotImplementedError

    def _commands_to_filters(self, cmds: list[dict], sim: Any, time_s: float) -> list[str]:
        raise NotImplementedError

    def _commands_shown(self, cmds: list[dict]) -> None:
        raise NotImplementedError

    def _after(self, step: TeamStep, outcome: FilterTick) -> None:
        raise NotImplementedError

    @property
    def on_worker_step(self) -> list[Callable[[TeamStep], None]]:
        """Called on the worker with each tick's step once its filters are fed (the window
        computes there what it will draw of the tick: ``app/ahead.py``); never called
        without a worker. Kept over a restart."""
        listeners = self.__dict__.get("_on_worker_step")
        if listeners is None:
            listeners = self.__dict__["_on_worker_step"] = []
        return listeners

    def start_worker(self) -> None:
        """Run the filters on a worker thread from now on (``runs/filter_worker``): a tick
        steps the simulation and hands the filters' part to the worker; :meth:`collect` shows
        the ticks it finished. The run is the same bit for bit (the same inputs, in the same
        order, the same recording); only when it is shown differs."""
        if self.worker is not None:
            return
        self._state = self._filter_tick(self.sim.tick, drawing=True)
        self._shown_at = (self.sim.tick, self.sim.time, self.sim.poses)
        self._slow_by_cpu(True)  # the worker's wall time includes waiting for the window
        self.worker = FilterWorker()
        for name in self.names:
            self._sync_status(name)

    def stop_worker(self, timeout: float | None = None) -> bool:
        """Finish the worker's ticks, show them, and run the filters in each tick again.
        With ``timeout`` [s] (a process that must end), whether the worker finished in time
        (if not, it is left behind and the ticks it did not finish are not shown)."""
        worker = self.worker
        if worker is None:
            return True
        ended = worker.wait(timeout) and worker.stop(timeout)
        if ended:
            self.collect()
        self.worker, self._state, self._waiting = None, None, []
        self._slow_by_cpu(False)
        self._beliefs.clear()
        if ended:
            for name in self.names:
                self._sync_status(name)
        return ended

    def _slow_by_cpu(self, on: bool) -> None:
        """The filters' slow warning ("slow: N ms per step") on the worker thread's CPU time
        (``on``), not its wall time, which includes waiting for the interpreter lock while
        the window draws; or on the wall time again."""
        for runner in self.filters_run.members:
            runner.slow_by_cpu = on
        self.filters_run.joint.slow_by_cpu = on

    @property
    def filters_behind(self) -> bool:
        """Whether the worker has ticks to finish or to show (the window then runs no new
        tick: the simulation slows down as it would with the filters in each tick)."""
        return self.worker is not None and (self.worker.busy or bool(self._waiting))

    def collect(self, each: Callable[[TeamStep], None] | None = None) -> int:
        """Show the ticks the worker finished, in order, up to the newest one it read for
        drawing (so every layer shows one tick); ``each(step)`` after each. Returns how many."""
        if self.worker is None:
            return 0
        self._waiting.extend(self.worker.results())
        last = max((k for k, (_, _, o) in enumerate(self._waiting) if o.drawing is not None),
                   default=-1)
        shown, self._waiting = self._waiting[:last + 1], self._waiting[last + 1:]
        for step, cmds, outcome in shown:
            self._commands_shown(cmds)
            self._after(step, outcome)
            if each is not None:
                each(step)
        return len(shown)

    def settle(self, each: Callable[[TeamStep], None] | None = None) -> int:
        """Wait for the worker's ticks and show them (a hot reload, a screenshot of the
        present); how many were shown."""
        if self.worker is None:
            return 0
        self.worker.wait()
        return self.collect(each)

    def settle_worker(self) -> None:
        """Wait until the worker has no tick left to finish (the ticks are not shown yet)."""
        if self.worker is not None:
            self.worker.wait()

    def _filter_job(self, recorded: tuple, cmds: list[dict], time_s: float, step: TeamStep,
                    last: bool) -> tuple[TeamStep, list[dict], FilterTick]:
        """One tick's filter work, on the worker, as :meth:`tick` does it without one: the
        recording, the filters' part of the commands (at simulated time ``time_s`` [s]), the
        filters fed; what the window draws of them when ``last``."""
        if self.recorder is not None:
            self.recorder.record_tick(*recorded)
        if cmds:
            self._commands_to_filters(cmds, None, time_s)
        self.filters_run.feed(step)
        self._fail_time = step.time
        for listener in self.__dict__.get("_on_worker_step", ()):
            listener(step)
        return step, cmds, self._filter_tick(step.tick, drawing=last)

    def _drawn(self) -> Drawing | None:
        """What the worker read for drawing after the tick shown (``filter_snapshot.Drawing``)."""
        return None if self._state is None else self._state.drawing


__all__ = ["FilterWorker", "WorkerTicks"]
