"""A filter in a child process of its own (the grader's side): :class:`FilterChild` starts
and talks to the child (:mod:`beacon_sim.hosting.child`, contained as
:mod:`beacon_sim.hosting.containment` says). Front ends reach it through the hosting
layer's one client (:mod:`beacon_sim.hosting.client`), which starts it and feeds it
batches of runs (:func:`~beacon_sim.hosting.feed.feed_batch`).

The child gets only what a filter may see: its :class:`~beacon_sim.filters.base.FilterContext`
(beacon map, dt, motion noise, sensors, parameters, its random generator), its initial
belief, then each tick's control, dt and readings, in lockstep (tick k+1 is sent only
after estimate k came back). A child that dies, breaks the protocol or does not answer in
time fails with the real reason (:func:`~beacon_sim.hosting.containment.exit_reason`),
as a :class:`~beacon_sim.hosting.watchdog.FilterFailed` whose message is that reason.
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import os
import shutil
import signal
import subprocess
from pathlib import Path
from typing import Any

import numpy as np

from beacon_sim.filters.base import (
    FilterContext,
    GaussianBelief,
)
from beacon_sim.hosting.containment import (
    Launched,
    Limits,
    ModuleSource,
    disk_used,
    exit_reason,
    launch,
)
from beacon_sim.hosting.watchdog import FilterFailed
from beacon_sim.hosting.wire import (
    EST_ENTRY,
    ESTIMATE,
    FAIL,
    JOINT,
    MAX_BATCH,
    MULTI,
    OK,
    REPORT,
    WireError,
    decode_joint,
    encode_batch,
    encode_request,
    parse_json,
    parse_multi,
    read_reply,
    send_frame,
)

#: The longest the grader waits for one answer of a child [s] of wall time, at least: a
#: filter that sleeps (uses no CPU, so its CPU-time limit never comes) is stopped then.
MIN_REPLY_TIMEOUT_S = 60.0
#: A child's log beyond this many bytes is not appended to by its successors [bytes].
MAX_LOG_BYTES = 1 << 20


class ChildFailure(FilterFailed):
    """The child reported its filter's failure, or died: ``str`` is the one line, ``tb``
    the traceback it sent (if any), ``died`` whether the process is gone."""

    def __init__(self, why: str, tb: str = "", died: bool = False):
        super().__init__(why)
        self.tb, self.died = tb, died


class FilterChild:
    """One student's child process, started fresh from a clean interpreter; it may serve
    all of that student's runs (one filter object at a time), never another student's.

    Parameters
    ----------
    source : Path or ModuleSource
        The student's file, or the module filter's package
        (:func:`~beacon_sim.hosting.sources.hosted_source`), copied read-only into the
        child's own folder.
    class_name : str or None
        The filter class (None: the class that implements the interface, else the file's
        functions; ``functions``: the functions).
    log : Path
        The student's log: the child's stdout and stderr, cut at ``limits.log_bytes``.
    sandbox : str
        ``bwrap`` or ``process`` (:func:`~beacon_sim.hosting.containment.resolve_sandbox`).
    limits : Limits
        Memory, CPU, file size and log limits of the child.
    reply_timeout_s : float
        The longest wait for one answer [s] of wall time.
    """

    def __init__(self, source: Path | ModuleSource, class_name: str | None, log: Path, sandbox: str,
                 limits: Limits, reply_timeout_s: float = MIN_REPLY_TIMEOUT_S):
        self.limits, self.sandbox = limits, sandbox
        self.source_name = source.name
        self.reply_timeout_s = reply_timeout_s
        self._waited_s = reply_timeout_s  # the last request's time-out [s]
        self.dead: str | None = None
        #: The CPU time [s] the child said it had used at its last report (the end of a run):
        #: its own word, for the cost figures only (benchmarks/bench_grade.py), never a grade's.
        self.reported_cpu_s = 0.0
        log.parent.mkdir(parents=True, exist_ok=True)
        self._log = open(os.devnull if log.exists() and log.stat().st_size > MAX_LOG_BYTES else log, "ab")
        self._proc: Launched | None = launch(source, self._log, sandbox, limits)
        try:
            doc = self.call_json("load", self._proc.source_in_child, class_name)
        except BaseException:
            self.close()
            raise
        self.class_name: str = str(doc.get("name", "?"))
        self.form: str = str(doc.get("form", "class"))
        self.info = doc  # missing methods, sensor kinds, module: what ``check`` reports

    # -- the pipe -------------------------------------------------------------------
    def request(self, frame: bytes, expect: int | None = None, runs: int = 1) -> tuple[bytes, bytes]:
        """Send a frame made by :func:`~beacon_sim.hosting.wire.encode_request` and read the
        answer (``expect``: its likely size [bytes], read at once; ``runs``: how many runs'
        steps it carries, each given the reply time-out); a FAIL answer or a dead child
        raises :class:`ChildFailure`."""
        if self.dead is not None or self._proc is None:
            raise ChildFailure(self.dead or "the filter's process is closed", died=True)
        try:
            self._waited_s = self.reply_timeout_s * runs
            send_frame(self._proc.to_child, frame)
            tag, payload = read_reply(self._proc.from_child, self._waited_s, expect)
        except (WireError, OSError) as exc:
            raise ChildFailure(self._death(exc), died=True) from None
        if tag == FAIL:
            doc = parse_json(payload)
            why = str(doc.get("why", "the filter failed"))  # the child's copy named as the file
            why = why.replace(self._proc.source_in_child, self.source_name)
            raise ChildFailure(why[:400], str(doc.get("tb", "")))
        return tag, payload

    def call(self, op: str, *args: Any) -> tuple[bytes, bytes]:
        """One request ``(op, *args)`` and its answer (see :meth:`request`)."""
        return self.request(encode_request(op, *args))

    def call_json(self, op: str, *args: Any) -> dict[str, Any]:
        """A request whose answer is OK or REPORT with a JSON object."""
        try:
            tag, payload = self.call(op, *args)
            if tag not in (OK, REPORT):
                raise WireError(f"broke the protocol (answered {op} with {tag!r})")
            return parse_json(payload)
        except WireError as exc:
            raise ChildFailure(self._death(exc), died=True) from None

    def _death(self, exc: BaseException) -> str:
        """Why the child cannot go on, in words; it is stopped if still running."""
        proc = self._proc
        text = str(exc)
        if proc is None:
            self.dead = "the filter's process is closed"
            return self.dead
        if "no answer in time" in text:
            self.kill()
            self.dead = (f"the filter's process did not answer for {self._waited_s:g} s "
                         "(wall time) and was stopped")
        elif "broke the protocol" in text:
            self.kill()
            self.dead = f"the filter's process {text} and was stopped"
        else:
            try:
                code: int | None = proc.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.kill()
                code = None
            self.dead = exit_reason(code, self.sandbox, self.limits)
        return self.dead

    def disk_problem(self) -> str | None:
        """At the process level, the words of the disk limit when what the child wrote
        (:func:`~beacon_sim.hosting.containment.disk_used`) is over it; None when it is not
        (under bubblewrap the file systems' sizes enforce it: a write over it fails)."""
        proc = self._proc
        if proc is None or proc.sandbox != "process":
            return None
        used = disk_used(proc.tmp / "work", proc.lease.uid if proc.lease is not None else None)
        if used <= self.limits.disk_bytes:
            return None
        return (f"disk limit: the filter's process wrote {used / 2**20:.1f} MB, over "
                f"{self.limits.disk_bytes / 2**20:g} MB (disk_limit_mb)")

    def kill(self) -> None:
        """Stop the child and everything it started (its session)."""
        proc = self._proc
        if proc is None or proc.proc.poll() is not None:
            return
        with contextlib.suppress(OSError):
            os.killpg(proc.proc.pid, signal.SIGKILL)
        with contextlib.suppress(subprocess.TimeoutExpired):
            proc.proc.wait(timeout=10)

    def close(self) -> None:
        """Close the pipe (the child exits), stop it if it does not, remove its folder."""
        proc, self._proc = self._proc, None
        if proc is None:
            return
        for fd in (proc.to_child, proc.from_child):
            with contextlib.suppress(OSError):
                os.close(fd)
        try:
            proc.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            with contextlib.suppress(OSError):
                os.killpg(proc.proc.pid, signal.SIGKILL)
            with contextlib.suppress(subprocess.TimeoutExpired):
                proc.proc.wait(timeout=10)
        with contextlib.suppress(OSError):
            os.killpg(proc.proc.pid, signal.SIGKILL)  # anything it left running
        shutil.rmtree(proc.tmp, ignore_errors=True)
        if proc.lease is not None:  # its user's processes and files, then the user ID
            proc.lease.release()
        self._log.close()

    def __enter__(self) -> FilterChild:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- the end of a run ------------------------------------------------------------
    def end(self) -> dict[str, Any]:
        """End the run: whether the filter drew from the global ``np.random`` / ``random``."""
        return self._report(self.call_json("end"))

    def _report(self, doc: dict[str, Any]) -> dict[str, Any]:
        cpu = doc.pop("cpu_s", None)
        if isinstance(cpu, int | float) and not isinstance(cpu, bool) and 0.0 <= cpu < 1e9:
            self.reported_cpu_s = float(cpu)
        return doc

    # -- a batch of runs: one filter per seed, one exchange per tick ------------------
    def call_multi(self, frame: bytes, count: int) -> list[tuple[bytes, bytes]] | np.ndarray:
        """Send a batch request of ``count`` runs and read its MULTI answer
        (:func:`~beacon_sim.hosting.wire.parse_multi`); anything else from the child, or a
        malformed answer, stops it (:class:`ChildFailure`, ``died``)."""
        tag, payload = self.request(frame, 5 + count * EST_ENTRY.itemsize, max(1, count))
        try:
            if tag != MULTI:
                raise WireError(f"broke the protocol (answered a batch with {tag!r})")
            return parse_multi(payload, count)
        except WireError as exc:
            raise ChildFailure(self._death(exc), died=True) from None

    def failure_text(self, payload: bytes) -> str:
        """The one line of a FAIL entry of a MULTI answer, the child's copy named as the file."""
        try:
            doc = parse_json(payload)
        except WireError as exc:
            raise ChildFailure(self._death(exc), died=True) from None
        why = str(doc.get("why", "the filter failed"))
        if self._proc is not None:
            why = why.replace(self._proc.source_in_child, self.source_name)
        return why[:400]

    def batch_build(self, builds: list[tuple[FilterContext, GaussianBelief | None, str]],
                    global_seed: int, run_limit_s: float | None) -> list[str | None]:
        """Build one fresh filter per run of a batch (``(ctx, initial, spec)`` each), each with
        its own CPU-time budget ``run_limit_s`` [s], the global RNGs seeded once from
        ``global_seed`` (derived from the run's key, never its seed): None per built filter,
        else why its construction failed. (:func:`~beacon_sim.hosting.feed.feed_batch`
        drives a batch.)"""
        if not 1 <= len(builds) <= MAX_BATCH:
            raise ValueError(f"a batch of {len(builds)} runs: expected 1 to {MAX_BATCH}")
        # Each its own copy of the world (no cached properties: a read-only mapping cannot be
        # pickled) and of its generator (runs built from one context must not share one).
        builds = [(dataclasses.replace(ctx, world=dataclasses.replace(ctx.world), rng=copy.deepcopy(ctx.rng)),
                   initial, spec) for ctx, initial, spec in builds]
        got = self.call_multi(encode_request("bbuild", builds, int(global_seed), run_limit_s), len(builds))
        assert isinstance(got, list)  # OK and FAIL entries, never all ESTIMATE
        return [None if tag == OK else self.failure_text(payload) for tag, payload in got]

    def _entries(self, op: str, slots: list[int]) -> list[tuple[bytes, bytes]]:
        got = self.call_multi(encode_request(op, slots), len(slots))
        if isinstance(got, np.ndarray):  # every entry an ESTIMATE, read as records
            return [(ESTIMATE, e.tobytes()[5:]) for e in got]
        return got

    def batch_first(self, slots: list[int]) -> list[tuple[bytes, bytes]]:
        """The estimate after reset of the runs ``slots`` of the batch: per run (ESTIMATE,
        payload) or (FAIL, why there is none): the run goes on either way."""
        return self._entries("bfirst", slots)

    def batch_belief(self, slots: list[int]) -> list[tuple[bytes, bytes]]:
        """``belief()`` of the runs ``slots`` at the end of the batch: per run (OK, b"") or
        (FAIL, what is wrong with it)."""
        return self._entries("bbelief", slots)

    def batch_step(self, slots: list[int], bodies: list[bytes]) -> list[tuple[bytes, bytes]] | np.ndarray:
        """One tick of the runs ``slots`` of the batch (their "step" requests' pickles, in
        order; a run not named is not stepped): a record array of their estimates (every one
        answered), else one (tag, payload) per run, ESTIMATE or FAIL (that run is switched off)."""
        return self.call_multi(encode_batch("bstep", bodies, slots), len(bodies))

    def final_joint(self, slot: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """The final ``joint()`` (mean (3 + 2M,), cov, landmark IDs (M,)) of run ``slot`` of
        the batch (None: of the one filter), checked
        (:func:`~beacon_sim.hosting.wire.decode_joint`), or None when the filter reports none.
        Asked one run at a time (a joint of 500 landmarks is 8 MB)."""
        if self.info.get("joint") is not True:
            return None
        frame = encode_request("joint") if slot is None else encode_request("bjoint", [slot])
        got = self.call_multi(frame, 1)
        if isinstance(got, np.ndarray):
            return None
        tag, payload = got[0]
        return decode_joint(payload) if tag == JOINT else None

    def batch_end(self) -> dict[str, Any]:
        """End the batch: whether its filters drew from the global ``np.random`` / ``random``."""
        return self._report(self.call_json("bend"))


__all__ = ["MIN_REPLY_TIMEOUT_S", "ChildFailure", "FilterChild"]
