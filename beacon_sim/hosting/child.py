"""The child process that hosts one student's filter: ``python -m beacon_sim.hosting.child
CONFIG_JSON`` with the grader's requests on stdin, its replies to stdout and its log on
stderr (started by :mod:`beacon_sim.hosting.isolated`, never by hand). It moves the two
pipes to fresh descriptors and points stdout at the log before any student code runs, so
nothing of the grader's process (its descriptor numbers) reaches it.

It starts from a clean interpreter (no fork of the grader: nothing of the grader's memory,
no truth, no other student's results), contains itself before any student code runs
(resource limits; bounded stdout and stderr; a user of its own when started as root
outside a sandbox, :mod:`beacon_sim.hosting.child_users`; the kernel's refusal of new
processes, signals to others and tracing, :mod:`beacon_sim.hosting.syscall_filter`), then
serves requests over the pipe in lockstep (:mod:`beacon_sim.hosting.wire`): it receives
only what a filter may see (its ``FilterContext``, its initial belief, then each tick's
control, dt and readings) and answers with estimates. The global ``random`` and
``np.random`` generators are seeded with a number the grader derives from the run's key and the filter's name
(:func:`~beacon_sim.core.streams.keyed_global_seed`), never with the run's seed, and the end
of a run reports whether the filter drew from them. Nothing the child is given holds the
run's seed (docs/grading.md, "What a filter can learn").
"""

from __future__ import annotations

import io
import json
import os
import random
import sys
from typing import Any

from beacon_sim.filters import MOVED
from beacon_sim.filters.registry import builtin_modules
from beacon_sim.hosting.batch import Batch, joint_entry, map_of, timed_step

#: Modules loaded before privileges are dropped (a root grader without a sandbox runs the
#: child as a user of its own, who may not be able to read the Python installation afterwards): the
#: standard library a filter may use, the core's models, the filters' shared home, every
#: built-in filter's module (from the registry: a new filter is never missed) and the old
#: paths of those that moved into a family.
PRELOAD = ("numpy", "numpy.linalg", "numpy.random", "math", "cmath", "random", "collections",
           "dataclasses", "functools", "itertools", "typing", "copy", "inspect", "gc", "abc",
           "enum", "statistics", "bisect", "heapq", "operator", "warnings", "csv", "html",
           "tomllib", "re", "string", "textwrap", "pathlib", "datetime", "decimal", "fractions",
           "array", "queue", "threading", "logging", "contextlib", "numbers", "pprint",
           "beacon_sim.core.scenario", "beacon_sim.core.simulation",
           "beacon_sim.core.angles", "beacon_sim.core.measurement_models", "beacon_sim.core.motion",
           "beacon_sim.filters.base", "beacon_sim.filters.association", "beacon_sim.filters.resampling",
           *builtin_modules(), *MOVED)
NOBODY = 65534
#: Why the kernel does not refuse new processes, signals to others and tracing in this
#: child (:mod:`beacon_sim.hosting.syscall_filter`), or None when it does.
KERNEL_BLOCK: str | None = "not installed"



class _BoundedOutput(io.TextIOBase):
    """``sys.stdout`` / ``sys.stderr`` of the child: written straight to the log's file
    descriptor up to ``limit`` bytes, then one line saying the rest was cut."""

    def __init__(self, fd: int, limit: int, shared: list[int]):
        self._fd, self._limit, self._used = fd, limit, shared

    def write(self, s: str) -> int:
        if self._used[0] < self._limit:
            data = s.encode("utf-8", "replace")[: self._limit - self._used[0]]
            self._used[0] += len(data)
            try:
                os.write(self._fd, data)
                if self._used[0] >= self._limit:
                    os.write(self._fd, f"\n[output cut at {self._limit} bytes]\n".encode())
            except OSError:
                pass
        return len(s)

    def writable(self) -> bool:
        return True

    def flush(self) -> None:
        pass


def _contain(cfg: dict[str, Any]) -> None:
    """Resource limits (the hard limit equal to the soft one: the filter cannot raise them),
    bounded output, then (root, no sandbox) the unprivileged user."""
    import resource

    def limit(which: int, value: int) -> None:
        try:
            _, hard = resource.getrlimit(which)
            v = value if hard == resource.RLIM_INFINITY else min(value, hard)
            resource.setrlimit(which, (v, v))
        except (ValueError, OSError):
            pass

    limit(resource.RLIMIT_CORE, 0)
    if cfg.get("fsize_bytes"):
        limit(resource.RLIMIT_FSIZE, int(cfg["fsize_bytes"]))
    if cfg.get("memory_bytes"):
        limit(resource.RLIMIT_AS, int(cfg["memory_bytes"]))
    if cfg.get("cpu_s"):
        try:
            _, hard = resource.getrlimit(resource.RLIMIT_CPU)
            soft = int(cfg["cpu_s"])
            resource.setrlimit(resource.RLIMIT_CPU, (soft, soft + 5 if hard == resource.RLIM_INFINITY
                                                      else min(soft + 5, hard)))
        except (ValueError, OSError):
            pass
    shared = [0]
    sys.stdout = _BoundedOutput(1, int(cfg.get("log_bytes", 1 << 20)), shared)
    sys.stderr = _BoundedOutput(2, int(cfg.get("log_bytes", 1 << 20)), shared)
    if cfg.get("drop_user") and hasattr(os, "geteuid") and os.geteuid() == 0:
        import importlib

        limit(resource.RLIMIT_NPROC, 256)  # the tasks (threads) of its user: no fork bomb

        for name in PRELOAD:
            try:
                importlib.import_module(name)
            except ImportError:
                pass
        uid = int(cfg.get("uid", NOBODY))  # its own user, from the grader's reserved range
        os.setgroups([])
        os.setgid(uid)
        os.setuid(uid)


def _np_state() -> Any:
    import numpy as np

    return np.random.get_state(legacy=False)  # noqa: NPY002 - the check of its use


def _same_np(a: Any, b: Any) -> bool:
    import numpy as np

    return (a["bit_generator"] == b["bit_generator"] and np.array_equal(a["state"]["key"], b["state"]["key"])
            and a["state"]["pos"] == b["state"]["pos"] and a["has_gauss"] == b["has_gauss"]
            and a["gauss"] == b["gauss"])


class Server:
    """The requests of :mod:`beacon_sim.hosting.isolated`, one at a time. Its replies go to
    the pipe ``wfd``, or to ``sink`` (the same server in the grader's own process:
    :class:`~beacon_sim.hosting.feed.LocalChild`)."""

    def __init__(self, wfd: int | None, sink: Any = None):
        self.wfd = wfd
        self.sink = sink
        self.cls: type | None = None
        self.flt: Any = None
        self.limit: Any = None   # the run's CPU-time limit, armed from build to end
        self.limit_s: float | None = None
        self.rng_states: tuple[Any, Any] | None = None
        self.step_limit_s: float | None = None  # each request's CPU-time limit (check)
        self.batch: Batch | None = None
        self.file: tuple[str, str | None] | None = None  # the student's file and class name

    def step_limited(self, fn: Any) -> Any:
        """``fn()`` under the step limit, if one is set: over it, the step's one line."""
        if self.step_limit_s is None:
            return fn()
        from beacon_sim.hosting.watchdog import FilterFailed, FilterTimeout, time_limit

        try:
            with time_limit(self.step_limit_s, cpu=True, backstop=False):
                return fn()
        except FilterTimeout:
            raise FilterFailed(f"time limit: a step took over {self.step_limit_s:g} s of CPU") from None

    def send(self, frame: bytes) -> None:
        from beacon_sim.hosting.wire import send_frame

        if self.sink is not None:
            self.sink(frame)
            return
        assert self.wfd is not None
        send_frame(self.wfd, frame)

    def fail(self, why: str, tb: str = "") -> None:
        from beacon_sim.hosting.wire import FAIL, reply_json

        self.send(reply_json(FAIL, {"why": why, "tb": tb}))

    def handle(self, req: tuple[Any, ...]) -> None:
        from beacon_sim.hosting.wire import OK, reply_json

        op = req[0]
        getattr(self, "op_" + op)(*req[1:])
        if op in ("predict", "update", "reset"):
            self.send(reply_json(OK, {}))

    def op_load(self, path: str, class_name: str | None) -> None:
        from pathlib import Path

        from beacon_sim.hosting.loading import choose_filter, import_file
        from beacon_sim.hosting.wire import OK, reply_json

        if path.startswith("module:"):  # a module filter: its package copied onto the path
            import importlib

            from beacon_sim.hosting.loading import IMPORT_LIMIT_S
            from beacon_sim.hosting.runner import run_filter_code

            name = path.removeprefix("module:")
            module = run_filter_code(lambda: importlib.import_module(name), IMPORT_LIMIT_S, "import")
            self.cls = choose_filter(module, class_name, name)
        else:
            module = import_file(Path(path), "student")
            self.cls = choose_filter(module, class_name, Path(path).name)
            # kept as chosen, not as asked: "file.py:Class" (check) and "file.py" (grade)
            # leave the same trace in the child when they choose the same class
            chosen = self.cls.__qualname__
            named = chosen == "functions" or getattr(module, chosen, None) is self.cls
            self.file = (path, chosen if named else class_name)
        form = "functions" if self.cls.__qualname__ == "functions" else "class"
        missing = [m for m in ("reset", "predict", "update", "estimate", "belief")
                   if not callable(getattr(self.cls, m, None))]
        kinds = getattr(self.cls, "sensor_kinds", None)
        kinds = [str(k) for k in kinds] if isinstance(kinds, list | tuple) else None
        self.send(reply_json(OK, {"name": self.cls.__qualname__, "form": form, "missing": missing,
                                  "module": str(self.cls.__module__), "sensor_kinds": kinds,
                                  "supports_global": bool(getattr(self.cls, "supports_global", False)),
                                  "landmarks": callable(getattr(self.cls, "landmarks", None)),
                                  "joint": callable(getattr(self.cls, "joint", None)),
                                  "syscall_filter_off": KERNEL_BLOCK}))

    def op_build(self, ctx: Any, initial: Any, global_seed: int, run_limit_s: float | None,
                 spec: str, step_limit_s: float | None = None) -> None:
        from beacon_sim.hosting.loading import build_from_context
        from beacon_sim.hosting.watchdog import time_limit
        from beacon_sim.hosting.wire import OK, reply_json

        self.end_limit()
        np_random_seed(global_seed)
        self.rng_states = (_np_state(), random.getstate())
        cls = self.cls if self.cls is not None else self.fresh_class()
        self.flt = build_from_context(cls, ctx, initial, spec)
        self.limit_s, self.step_limit_s = run_limit_s, step_limit_s
        if run_limit_s is not None:
            self.limit = time_limit(run_limit_s, cpu=True, backstop=False)
            self.limit.__enter__()
        self.send(reply_json(OK, {}))

    def op_step(self, control: Any, dt: float, measurements: Any, want_prior: bool) -> None:
        from beacon_sim.hosting.guard import estimate_arrays
        from beacon_sim.hosting.wire import reply_estimate

        f = self.flt

        def step() -> tuple[int, Any, Any, bytes | str | None]:
            wall, prior, est = timed_step(f, control, dt, measurements, want_prior)
            return wall, prior, est, map_of(f)

        wall, prior, est, block = self.step_limited(step)
        post = estimate_arrays(est)
        if isinstance(post, str):
            return self.loose(est) if self.step_limit_s is not None else self.fail(post)
        pri: Any = None
        if want_prior:
            pri = estimate_arrays(prior)
            if isinstance(pri, str):
                return self.fail("after predict: " + pri)
        if isinstance(block, str):  # the map's fault as data: the grader decides (wire.py)
            from beacon_sim.hosting.wire import map_fault_block

            block = map_fault_block(block)
        self.send(reply_estimate(wall, pri, post, block))
        return None

    def loose(self, est: Any) -> None:
        """An unusable estimate sent as it is, for ``check`` to judge (the step limit is set
        only there): arrays of numbers of any shape, or what it was instead."""
        import numpy as np

        from beacon_sim.hosting.wire import encode_belief

        if isinstance(est, tuple | list) and len(est) == 2:
            try:
                arrays = [np.asarray(est[0], dtype=float), np.asarray(est[1], dtype=float)]
                if all(a.size <= 10_000 for a in arrays):
                    self.send(encode_belief("estimate", arrays, {}))
                    return
            except (TypeError, ValueError):
                self.send(encode_belief("estimate-unusable", [], {"pair": True}))
                return
        self.send(encode_belief("estimate-unusable", [], {"pair": False, "none": est is None}))

    def op_predict(self, control: Any, dt: float) -> None:
        self.step_limited(lambda: self.flt.predict(control, dt))

    def op_update(self, measurements: Any) -> None:
        self.step_limited(lambda: self.flt.update(measurements))

    def op_reset(self, initial: Any) -> None:
        self.step_limited(lambda: self.flt.reset(initial))

    def op_estimate(self) -> None:
        from beacon_sim.hosting.guard import estimate_arrays
        from beacon_sim.hosting.wire import reply_estimate

        est = self.step_limited(self.flt.estimate)
        post = estimate_arrays(est)
        if isinstance(post, str):
            return self.loose(est) if self.step_limit_s is not None else self.fail(post)
        self.send(reply_estimate(0, None, post))
        return None

    def op_landmarks(self) -> None:
        """The filter's map now (a MAPPED reply whose estimate part is NaN), for a proxy asked
        for ``landmarks()`` outside a step (after reset)."""
        import numpy as np

        from beacon_sim.hosting.wire import reply_estimate

        block = self.step_limited(lambda: map_of(self.flt))
        if not isinstance(block, bytes):
            return self.fail(block or "the filter has no landmarks()")
        nan = (np.full(3, np.nan), np.full((3, 3), np.nan))
        self.send(reply_estimate(0, None, nan, block))
        return None

    def op_belief(self) -> None:
        import numpy as np

        from beacon_sim.filters.base import GaussianBelief, GridBelief, ParticleBelief
        from beacon_sim.hosting.wire import encode_belief

        b = self.step_limited(self.flt.belief)
        if isinstance(b, GaussianBelief):
            self.send(encode_belief("gaussian", [b.mean, b.cov], {}))
        elif isinstance(b, ParticleBelief):
            self.send(encode_belief("particles", [b.poses, b.weights], {}))
        elif isinstance(b, GridBelief):
            self.send(encode_belief("grid", [b.prob, np.asarray(b.origin), np.asarray(b.cell)], {}))
        else:
            self.fail(f"belief() returned {type(b).__name__}, expected a GaussianBelief, "
                      "ParticleBelief or GridBelief")

    # -- a batch: one filter per seed, one exchange per tick for all of them -------------
    def op_bbuild(self, builds: list[tuple[Any, Any, str]], global_seed: int,
                  run_limit_s: float | None) -> None:
        """Build one filter per run of the batch (``(ctx, initial, spec)`` each, as
        :meth:`op_build`), the global RNGs seeded once from ``global_seed``; each run has
        its own CPU-time budget ``run_limit_s``. Answers MULTI: OK or FAIL per run. Nothing
        says which run is scored and which is a probe (:mod:`beacon_sim.hosting.feed`)."""
        self.end_limit()
        self.release()
        np_random_seed(global_seed)
        self.rng_states = (_np_state(), random.getstate())
        self.batch = Batch(self.fresh_class, builds, run_limit_s, all_threads=self.sink is None)
        self.send(self.batch.built)

    def op_bfirst(self, slots: list[int]) -> None:
        """The estimate after reset of the runs ``slots`` (each under its run's budget):
        MULTI, per run an ESTIMATE (any arrays of the right shapes) or a FAIL entry saying
        why there is none; the run goes on either way (``check`` judges it)."""
        assert self.batch is not None
        self.send(self.batch.firsts(slots))

    def op_bbelief(self, slots: list[int]) -> None:
        """``belief()`` of the runs ``slots`` at the end of the batch: MULTI, per run OK or a
        FAIL entry saying what is wrong with it (it raised, or is not a belief); the runs
        are over, so nothing is switched off (``check`` and ``grade`` report it)."""
        assert self.batch is not None
        self.send(self.batch.beliefs(slots))

    def release(self) -> None:
        """Drop the previous batch's filters and the copies of the student's file they came
        from (the file is imported afresh for every filter), and collect them, so that a new
        batch starts with the whole memory limit: nothing of a run's memory is left for the
        next (a table at module level included)."""
        import gc

        self.flt = None
        self.batch = None
        if self.sink is not None:  # in the grader's own process: nothing of the student's here
            return
        if self.file is not None:  # the loaded copy too: every build imports its own
            self.cls = None
            sys.modules.pop("student", None)
        gc.collect()

    def fresh_class(self) -> type:
        """The filter class of a fresh copy of the student's file (imported again: its own
        module-level state, as a file of functions keeps), so that no state crosses the runs
        of a batch; a module filter's class as loaded."""
        if self.file is None:
            assert self.cls is not None
            return self.cls
        from pathlib import Path

        from beacon_sim.hosting.loading import choose_filter, import_file

        path, class_name = self.file
        self.cls = None  # the previous copy belongs to its filter alone
        self.cls = choose_filter(import_file(Path(path), "student"), class_name, Path(path).name)
        return self.cls

    def op_bstep(self, bodies: list[bytes], slots: list[int]) -> None:
        """One tick of the runs ``slots`` of the batch (``bodies``: their "step" requests
        pickled); a run not named is not stepped (it ended or failed). Answers MULTI:
        ESTIMATE or FAIL per run named, in order; a failed run may not be named again."""
        assert self.batch is not None
        self.send(self.batch.step(slots, bodies))

    def op_bjoint(self, slots: list[int]) -> None:
        """The final ``joint()`` (mean, cov, landmark IDs) of the runs ``slots`` of the batch,
        for the joint NEES: MULTI, per run a JOINT entry (the three as float arrays) or OK
        (no ``joint()``, it raised or ran out of its run's time, or a map over
        :data:`~beacon_sim.hosting.wire.MAX_JOINT_LANDMARKS`: not reported)."""
        assert self.batch is not None
        self.send(self.batch.joints(slots))

    def op_joint(self) -> None:
        """The final ``joint()`` of the one filter (as :meth:`op_bjoint`, one MULTI entry)."""
        from beacon_sim.hosting.watchdog import StepWatch
        from beacon_sim.hosting.wire import reply_multi

        self.send(reply_multi([joint_entry(self.flt, StepWatch(cpu=True), self.step_limit_s)]))

    def op_bend(self) -> None:
        """End the batch: whether its filters drew from the global generators."""
        self.batch = None
        self.op_end()

    def end_limit(self) -> None:
        if self.limit is not None:
            self.limit.__exit__(None, None, None)
            self.limit = None

    def op_end(self) -> None:
        from beacon_sim.hosting.wire import REPORT, reply_json

        self.end_limit()
        np_used = py_used = False
        if self.rng_states is not None:
            np_used = not _same_np(_np_state(), self.rng_states[0])
            py_used = random.getstate() != self.rng_states[1]
        import resource

        use = [resource.getrusage(w) for w in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN)]
        self.send(reply_json(REPORT, {"np_global": np_used, "py_global": py_used,
                                      "cpu_s": sum(u.ru_utime + u.ru_stime for u in use)}))


def np_random_seed(seed: int) -> None:
    """Seed the global generators with ``seed`` (any non-negative int; all of its low 128
    bits count), so that a global-RNG filter is reproducible. The grader sends a number
    derived from the run's key (:func:`~beacon_sim.core.streams.keyed_global_seed`), never
    the run's seed."""
    import numpy as np

    seed = int(seed) % 2**128
    words = [(seed >> (32 * k)) & 0xFFFFFFFF for k in range(4)]
    np.random.seed(np.array(words, dtype=np.uint32))  # noqa: NPY002 - a global-RNG filter is reproducible
    random.seed(seed)


def main(argv: list[str]) -> int:
    """Serve the grader until it closes the pipe."""
    cfg = json.loads(argv[0])
    rfd, wfd = os.dup(0), os.dup(1)  # the pipes, on descriptors of the child's own
    os.dup2(2, 1)  # stdout to the log, as stderr; stdin from nothing
    null = os.open(os.devnull, os.O_RDONLY)
    os.dup2(null, 0)
    os.close(null)
    import traceback  # noqa: F401 - everything the child needs, before it may lose the right to read it

    import beacon_sim.hosting.guard
    import beacon_sim.hosting.host
    import beacon_sim.hosting.loading
    import beacon_sim.hosting.processes
    import beacon_sim.hosting.watchdog  # noqa: F401
    from beacon_sim.hosting.wire import read_request

    _contain(cfg)
    from beacon_sim.hosting.processes import PROCESS_NOT_ALLOWED, become_subreaper
    from beacon_sim.hosting.syscall_filter import install, refuse_in_python

    become_subreaper()
    global KERNEL_BLOCK
    KERNEL_BLOCK = install() if cfg.get("syscall_filter", True) else "not asked for"
    if KERNEL_BLOCK is None:
        refuse_in_python(PROCESS_NOT_ALLOWED + " (refused by the kernel)")

    from beacon_sim.hosting.processes import stop_descendants

    server = Server(wfd)
    try:
        while True:
            req = read_request(rfd)
            if req is None:
                return 0
            if not serve_one(server, req, cfg):
                return 1
    finally:
        stop_descendants()  # nothing the student's code started outlives its process


def serve_one(server: Server, req: tuple[Any, ...], cfg: dict[str, Any]) -> bool:
    """Handle one request; a failure of the filter's code (or its time) goes back as one
    line. False when the answer could not be sent (the grader is gone)."""
    import traceback

    from beacon_sim.hosting.host import failure_of

    try:
        server.handle(req)
        return True
    except BaseException as exc:  # the filter's code (or its time): one line to the grader
        over = (f"time limit: over {server.limit_s:g} s of filter time in the run"
                if server.limit_s is not None else None)
        why = failure_of(exc, server.limit_s, over)
        if why is None:
            if server.sink is not None:  # in the grader's own process: the user's Ctrl-C
                raise
            why = f"{type(exc).__name__} raised by the filter"
        if req[0] == "build":
            why = "construction failed: " + why
        elif req[0] == "load":
            why = str(exc) if isinstance(exc, ValueError) else why
            if cfg.get("drop_user") and ("ModuleNotFoundError" in why or "PermissionError" in why):
                why += (" (as a user of its own, who cannot read this Python installation, only "
                        "preloaded modules import: use --sandbox bwrap)")
        try:
            server.fail(why, traceback.format_exc())
        except OSError:
            return False
        return True


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
