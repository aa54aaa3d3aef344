"""A student's limits are the student's: the CPU time of every thread its file starts counts
against a run's budget (a helper thread's work in the step, and between steps), a process
it starts fails its runs (its use could not be counted) and is killed, its total wall time
is capped; the verdicts are CPU-time verdicts, the same beside two busy-spinning processes."""

from __future__ import annotations

import dataclasses
import os
import textwrap
import time

import pytest

from beacon_sim.evaluation.grading import GradeConfig, grade

LIMIT_S = 1.0  # the runs' CPU-time budget in these tests [s]
#: two_rooms at 0.1 s a tick: 4 s is 40 ticks; each file's extra work is 0.08 s a tick,
#: 3.2 s in a run: over three times the budget when it is CPU, nothing when it is a wait.
CONFIG = GradeConfig(scenarios=("two_rooms",), seeds=(0, 1), duration=4.0, time_limit=LIMIT_S)

HEAD = textwrap.dedent("""
    import os
    import threading
    import time
    from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter


    def burn(seconds):
        t0 = time.thread_time()
        while time.thread_time() - t0 < seconds:
            pass
""")

FILES = {
    "honest": """
class Honest(ExtendedKalmanFilter):
    pass
""",
    "sleepy": """
class Sleepy(ExtendedKalmanFilter):
    def predict(self, control, dt):
        super().predict(control, dt)
        time.sleep(0.08)  # waits: no CPU
""",
    "helper": """
class Helper(ExtendedKalmanFilter):
    def predict(self, control, dt):
        super().predict(control, dt)
        t = threading.Thread(target=burn, args=(0.08,))  # the work in a helper thread
        t.start()
        t.join()
""",
    "between": """
class Between(ExtendedKalmanFilter):
    # Pipelined: each step hands work to a helper thread and returns at once; the next
    # step uses the result (waits for it). The helper works while the child waits for the
    # next tick, and on, into that step.
    def reset(self, initial):
        super().reset(initial)
        self.go, self.done = threading.Semaphore(0), threading.Semaphore(0)
        self.pending = False
        threading.Thread(target=self.work, daemon=True).start()

    def work(self):
        while True:
            self.go.acquire()
            burn(0.08)
            self.done.release()

    def predict(self, control, dt):
        if self.pending:
            self.done.acquire()  # the previous tick's result
        super().predict(control, dt)
        self.go.release()
        self.pending = True
""",
}


def _class(folder, extra=None):
    folder.mkdir()
    for name, body in {**FILES, **(extra or {})}.items():
        (folder / f"{name}.py").write_text(HEAD + body, encoding="utf-8")
    return folder


def test_every_threads_cpu_counts_and_a_wait_does_not_beside_a_busy_machine(tmp_path, busy_machine):
    board = grade(_class(tmp_path / "class"), CONFIG, jobs=2, secret=bytes(32))
    rows = {r["student"]: r for r in board.rows}
    assert not rows["honest"]["failed_runs"] and not rows["sleepy"]["failed_runs"], \
        (rows["honest"]["failures"], rows["sleepy"]["failures"])
    for name in ("helper", "between"):
        r = rows[name]
        assert r["failed_runs"] >= 2, (name, r["failures"])
        assert all("time limit: over 1 s of filter time" in f["reason"] for f in r["failures"]), r["failures"]
        assert any(f.startswith("limit hit: CPU time per run") for f in r["flags"]), r["flags"]
        assert r["rank"] > rows["honest"]["rank"] and r["rank"] > rows["sleepy"]["rank"]


def test_a_process_the_file_starts_fails_its_runs_and_is_killed(tmp_path):
    """At the process level (no PID namespace to end them with the sandbox): a double-forked,
    setsid'd grandchild that names itself (its comm), and os.system."""
    name = f"bs{os.getpid() % 4096:03x}{time.monotonic_ns() % 16**8:08x}"
    forks = f"""
import ctypes


class Forks(ExtendedKalmanFilter):
    def reset(self, initial):
        super().reset(initial)
        self.k = 0

    def predict(self, control, dt):
        super().predict(control, dt)
        self.k += 1
        if self.k == 3 and os.fork() == 0:  # a double fork: the grandchild is an orphan
            try:
                if os.fork() == 0:
                    os.setsid()
                    ctypes.CDLL(None).prctl(15, {name!r}.encode(), 0, 0, 0)  # PR_SET_NAME
                    time.sleep(600)
            finally:
                os._exit(0)
"""
    runs = """
class Runs(ExtendedKalmanFilter):
    def predict(self, control, dt):
        super().predict(control, dt)
        os.system("true")  # a process that runs and is reaped within the step
"""
    folder = tmp_path / "class"
    folder.mkdir()
    (folder / "forks.py").write_text(HEAD + forks, encoding="utf-8")
    (folder / "runs.py").write_text(HEAD + runs, encoding="utf-8")
    (folder / "honest.py").write_text(HEAD + FILES["honest"], encoding="utf-8")
    cfg = dataclasses.replace(CONFIG, sandbox="process", allow_unisolated=True)
    board = grade(folder, cfg, jobs=1, secret=bytes(32))
    rows = {r["student"]: r for r in board.rows}
    assert not rows["honest"]["failed_runs"]
    for student in ("forks", "runs"):
        r = rows[student]
        assert r["failed_runs"] >= 2 and all("started a process: not allowed" in f["reason"]
                                             for f in r["failures"]), (student, r["failures"])
        assert any(f.startswith("limit hit: processes") for f in r["flags"]), r["flags"]
    time.sleep(0.5)
    alive = []
    for pid in os.listdir("/proc"):  # nothing the file started outlives its grade
        try:
            with open(f"/proc/{pid}/comm", encoding="utf-8") as fh:
                if fh.read().strip() == name:
                    alive.append(pid)
        except (OSError, ValueError):
            continue
    assert not alive, alive


def test_a_students_total_wall_time_is_capped_and_said(tmp_path):
    folder = tmp_path / "class"
    folder.mkdir()
    (folder / "sleepy.py").write_text(HEAD + FILES["sleepy"], encoding="utf-8")
    cfg = GradeConfig(scenarios=("two_rooms",), seeds=(0, 1), duration=4.0, time_limit=30.0, total_time_s=2.0)
    t0 = time.monotonic()
    board = grade(folder, cfg, jobs=1, secret=bytes(32))
    assert time.monotonic() - t0 < 60.0  # the child was stopped, not waited for (generous)
    r = board.rows[0]
    assert r["failed_runs"] >= 2, r["failures"]
    assert all("total time limit: 2 s of wall time" in f["reason"] for f in r["failures"]), r["failures"]
    assert any(f.startswith("limit hit: total wall time") for f in r["flags"]), r["flags"]


def test_the_total_wall_time_holds_while_the_students_process_is_still_starting(tmp_path):
    """A file slow to import (as a loaded machine makes any file): the time runs out before
    the child is up, so there is no child to stop then; it is stopped as soon as it is."""
    folder = tmp_path / "class"
    folder.mkdir()
    slow = HEAD + "\nburn(3.0)  # at import: still starting when the time is up\n\n\n" + FILES["honest"]
    (folder / "slow.py").write_text(slow, encoding="utf-8")
    cfg = GradeConfig(scenarios=("two_rooms",), seeds=(0,), duration=2.0, time_limit=30.0, total_time_s=1.0)
    r = grade(folder, cfg, jobs=1, secret=bytes(32)).rows[0]
    assert r["failed_runs"] == 1, r["failures"]
    assert all("total time limit: 1 s of wall time" in f["reason"] for f in r["failures"]), r["failures"]


class _Sleeps:
    def __init__(self, ctx):
        time.sleep(0.6)  # waits: no CPU

    def reset(self, initial):
        pass


class _Burns(_Sleeps):
    def __init__(self, ctx):
        t0 = time.thread_time()
        while time.thread_time() - t0 < 0.6:
            pass


def test_construction_is_limited_by_cpu_time_in_a_grade_not_wall_time():
    """A hosted filter is built under a CPU-time limit (``cpu=True``: a constructor that
    waits for a core on a loaded machine is not failed, one that burns is); the window's
    build keeps its wall-time limit. Here with a 0.3 s limit."""
    from beacon_sim.core.scenario import load_scenario
    from beacon_sim.filters.base import FilterContext
    from beacon_sim.hosting.loading import build_from_context, initial_belief
    from beacon_sim.hosting.watchdog import FilterExit

    sc = load_scenario("two_rooms")
    ctx = FilterContext.of_scenario(sc, "x", {}, None)
    build_from_context(_Sleeps, ctx, initial_belief(sc), "x", limit_s=0.3, cpu=True)
    with pytest.raises(FilterExit, match="time limit"):
        build_from_context(_Burns, ctx, initial_belief(sc), "x", limit_s=0.3, cpu=True)
    with pytest.raises(FilterExit, match="time limit"):
        build_from_context(_Sleeps, ctx, initial_belief(sc), "x", limit_s=0.3)  # wall: the window's


def test_a_batch_builds_its_filters_under_the_cpu_time_limit(monkeypatch):
    import beacon_sim.hosting.loading as loading
    from beacon_sim.hosting.batch import Batch

    seen = []
    monkeypatch.setattr(loading, "build_from_context", lambda *a, **k: seen.append(k) or object())
    Batch(lambda: object, [(None, None, "x")], 1.0)
    assert seen == [{"cpu": True}]
