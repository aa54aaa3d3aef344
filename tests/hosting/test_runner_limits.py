"""The runner's time limits with StepWatch (the thread's watchdog entry armed in
place each step): an endless loop is still stopped, a CPU-time limit counts CPU and not
sleep, nothing is raised after a step has ended, limits nest, and the verdicts and figures
of working filters are those of the general ``time_limit``. Limits are generous and no
assertion depends on the machine's speed."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from beacon_sim.core.types import Step
from beacon_sim.hosting import watchdog
from beacon_sim.hosting.runner import FilterRunner
from beacon_sim.hosting.watchdog import FilterTimeout, StepWatch, time_limit


def _step(tick: int) -> Step:
    return Step(tick=tick, time=tick * 0.1, dt=0.1, control=None, measurements=[],
                true_pose=np.zeros(3))


class Plain:
    def __init__(self, work: float = 0.0, sleep: float = 0.0, loop_at: int | None = None):
        self.work, self.sleep, self.loop_at, self.n = work, sleep, loop_at, 0

    def predict(self, u, dt):
        self.n += 1
        if self.loop_at is not None and self.n >= self.loop_at:
            while True:
                pass
        if self.sleep:
            time.sleep(self.sleep)
        end = time.thread_time() + self.work
        while time.thread_time() < end:  # busy: CPU time
            pass

    def update(self, z):
        pass

    def estimate(self):
        return np.full(3, float(self.n)), np.eye(3)


def _feed(runner: FilterRunner, n: int) -> None:
    for k in range(n):
        runner.feed(_step(k))


@pytest.mark.parametrize("cpu", [False, True])
def test_an_endless_loop_is_stopped_and_the_others_go_on(cpu):
    runner = FilterRunner({"loops": Plain(loop_at=3), "ok": Plain()}, step_limit_s=0.3, cpu_limits=cpu)
    _feed(runner, 6)
    loops, ok = runner.tracks["loops"], runner.tracks["ok"]
    assert loops.failed == "time limit: a step took over 0.3 s" + (" of CPU" if cpu else "")
    assert loops.failed_time_s == pytest.approx(0.2) and loops.steps == 2
    assert ok.failed is None and ok.steps == 6
    assert [m[0] for m in ok.means] == [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]
    assert loops.step_ns >= 0.3e9  # the stopped step's time is counted


def test_a_cpu_limit_counts_cpu_not_sleep():
    # 0.4 s asleep in a step under a 0.2 s CPU limit: no time-out (the backstop is 11 s wall)
    runner = FilterRunner({"sleeps": Plain(sleep=0.4)}, step_limit_s=0.2, cpu_limits=True)
    _feed(runner, 1)
    assert runner.tracks["sleeps"].failed is None
    # the same under a wall-time limit is stopped
    runner = FilterRunner({"sleeps": Plain(sleep=0.4)}, step_limit_s=0.2)
    _feed(runner, 1)
    assert "time limit" in runner.tracks["sleeps"].failed
    # 1 s of CPU under a 0.2 s CPU limit is stopped
    runner = FilterRunner({"busy": Plain(work=1.0)}, step_limit_s=0.2, cpu_limits=True)
    _feed(runner, 1)
    assert runner.tracks["busy"].failed == "time limit: a step took over 0.2 s of CPU"


def test_the_run_limit_is_what_is_left_of_it():
    runner = FilterRunner({"busy": Plain(work=0.15)}, run_limit_s=0.5, cpu_limits=True)
    _feed(runner, 10)
    tr = runner.tracks["busy"]
    assert tr.failed == "time limit: over 0.5 s of filter CPU time in the run"
    # 3 steps of 0.15 s of CPU fit in 0.5 s, whatever the load: under CPU limits the run's
    # account is the filter thread's CPU time (a 0.15 s CPU step took 0.54 s wall at load 16)
    assert tr.steps == 3
    assert 0.45e9 <= tr.charged_ns <= 0.6e9


def test_nothing_is_raised_after_a_step_and_the_entry_stays_idle():
    watch = StepWatch()
    watch.seconds = 0.05
    for _ in range(3):  # steps that overrun their limit inside a C call (sleep), then end
        try:
            with watch:
                time.sleep(0.15)
        except FilterTimeout:
            pass
    time.sleep(0.3)  # a raise fired as a step ended would arrive here
    entry = watchdog._WD_ARMED[threading.get_ident()]
    assert entry is watchdog._WD_SLOTS[threading.get_ident()]
    assert entry[0] == float("inf") and entry[1] == 0.0 and entry[2] == -1.0


def test_step_watch_nests_with_time_limit():
    watch = StepWatch()
    watch.seconds = 30.0
    with pytest.raises(FilterTimeout), time_limit(0.2):  # an outer limit: the earlier deadline wins
        with watch:
            while True:
                pass
    with time_limit(30.0), watch:  # inside another limit it falls back and ends cleanly
        pass
    watch.seconds = 0.2
    with pytest.raises(FilterTimeout), time_limit(30.0), watch:
        while True:
            pass
    with watch:  # and afterwards it uses the thread's own entry again
        pass
    tid = threading.get_ident()
    assert watchdog._WD_ARMED[tid] is watchdog._WD_SLOTS[tid]


def test_step_watch_in_other_threads():
    results = {}

    def work(name):
        runner = FilterRunner({"loops": Plain(loop_at=2), "ok": Plain()}, step_limit_s=0.3)
        _feed(runner, 3)
        results[name] = (runner.tracks["loops"].failed, runner.tracks["ok"].steps)

    threads = [threading.Thread(target=work, args=(k,)) for k in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    assert results == {k: ("time limit: a step took over 0.3 s", 3) for k in range(2)}


def test_no_limit_no_watchdog_entry_armed():
    runner = FilterRunner({"ok": Plain()})
    _feed(runner, 3)
    entry = watchdog._WD_SLOTS.get(threading.get_ident())
    assert entry is None or entry[0] == float("inf")
    assert runner.tracks["ok"].steps == 3


def test_cpu_limits_set_after_construction_still_count():
    runner = FilterRunner({"sleeps": Plain(sleep=0.4)}, step_limit_s=0.2)
    runner.cpu_limits = True  # a CPU-time limit from now on: sleeping is not over it
    _feed(runner, 1)
    assert runner.tracks["sleeps"].failed is None


class Kept:
    """Returns the arrays it keeps (and a kept tuple, or a view) and changes them in place
    on the next step: the runner must have copied what it recorded."""

    def __init__(self, how: str):
        self.how, self.m, self.c = how, np.zeros(3), np.eye(3)
        self.pair = (self.m, self.c)

    def predict(self, u, dt):
        self.m += 1.0  # in place
        self.c *= 2.0

    def update(self, z):
        pass

    def estimate(self):
        if self.how == "tuple":
            return self.pair
        if self.how == "view":
            return self.m[:], self.c[:]
        return self.m, self.c


@pytest.mark.parametrize("how", ["arrays", "tuple", "view"])
def test_estimates_the_filter_keeps_are_recorded_as_they_were(how):
    runner = FilterRunner({"f": Kept(how)}, step_limit_s=10.0)
    _feed(runner, 4)
    tr = runner.tracks["f"]
    assert [m[0] for m in tr.means] == [1.0, 2.0, 3.0, 4.0]
    assert [c[0, 0] for c in tr.covs] == [2.0, 4.0, 8.0, 16.0]


def test_fresh_estimates_are_kept_without_a_copy_and_others_are_copied():
    from beacon_sim.hosting.guard import validate_estimate
    fresh = (np.zeros(3), np.eye(3))
    got = validate_estimate(fresh, sole=True)
    assert got[0] is fresh[0] and got[1] is fresh[1]  # nothing but `fresh` holds them
    held = fresh[0]
    got = validate_estimate(fresh, sole=True)
    assert got[0] is not held and got[1] is not fresh[1]  # one more holder: copied
    assert np.array_equal(got[0], held)
    del held
    got = validate_estimate(fresh)  # the default: always fresh copies
    assert got[0] is not fresh[0]


@pytest.mark.parametrize("cpu", [False, True])
def test_steps_ending_at_their_deadline_raise_nothing_afterwards(cpu):
    # steps that end just as their time is up, many times: a raise is either this step's
    # (the filter is stopped) or withdrawn, never delivered after the step
    class AtTheLine:
        def __init__(self, k):
            self.n, self.k = 0, k

        def predict(self, u, dt):
            self.n += 1
            end = time.thread_time() + 0.012 + 0.007 * ((self.n + self.k) % 7)
            while time.thread_time() < end:  # busy (CPU), 12 to 54 ms, around the 22 ms limit
                pass

        def update(self, z):
            pass

        def estimate(self):
            return np.zeros(3), np.eye(3)

    stopped = 0
    for k in range(8):
        runner = FilterRunner({"a": AtTheLine(k), "ok": Plain()}, step_limit_s=0.022, cpu_limits=cpu)
        _feed(runner, 3)
        stopped += runner.tracks["a"].failed is not None
        assert runner.tracks["ok"].steps == 3 and runner.tracks["ok"].failed is None
    time.sleep(0.3)  # a raise fired as a step ended, or re-fired, would arrive here
    entry = watchdog._WD_SLOTS[threading.get_ident()]
    assert entry[0] == float("inf") and entry[1] == 0.0 and entry[2] == -1.0
    assert watchdog._WD_ARMED[threading.get_ident()] is entry
    assert stopped >= 1  # some steps were over (the CPU count starts when the watchdog first looks)
