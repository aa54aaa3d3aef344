"""What the runner adds around a filter: the cost of one step through
``FilterRunner.feed`` minus the same filter's bare ``predict`` + ``update`` + ``estimate``,
CPU time (the process's: the watchdog thread's included), interleaved rounds (bare then
runner, runner then bare, ...), the median of the rounds' own differences, with their
quartiles (how decisive the median is).

Run:  python benchmarks/bench_runner.py [--quick]

Rows, with their targets: the runner's own cost per filter-step for a trivial filter
(no work: the pure overhead) and the EKF (4 bearings a step), <= 3 us each, and for the PF
with 100k particles <= 5 % of its step (its rounds vary by more than 3 us: the resampling
and the machine's load). The runner runs as ``beacon-sim run``
builds it (``HEADLESS_STEP_LIMIT_S``, wall-time limit), and with a CPU-time limit
(``cpu_limits=True``, what grading uses).
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np
from bench_goals import krejsa
from figures import figure

from beacon_sim.hosting.loading import build_filter
from beacon_sim.hosting.runner import HEADLESS_STEP_LIMIT_S, FilterRunner


class Trivial:
    """A filter that does nothing: its steps cost only the calls."""

    def __init__(self) -> None:
        self.m, self.c = np.zeros(3), np.eye(3)

    def reset(self, _=None) -> None:
        pass

    def predict(self, u, dt) -> None:
        pass

    def update(self, z) -> None:
        pass

    def estimate(self):
        return self.m, self.c


def bare(f, stp) -> float:
    """CPU time [s] of predict + update + estimate over ``stp``, called directly."""
    c = time.process_time()
    for st in stp:
        f.predict(st.control, st.dt)
        f.update(st.measurements)
        f.estimate()
    return time.process_time() - c


def through_runner(f, stp, cpu_limits) -> float:
    """CPU time [s] of the same steps through ``FilterRunner.feed`` (a fresh runner)."""
    runner = FilterRunner({"f": f}, step_limit_s=HEADLESS_STEP_LIMIT_S, cpu_limits=cpu_limits)
    c = time.process_time()
    for st in stp:
        runner.feed(st)
    spent = time.process_time() - c
    tr = runner.tracks["f"]
    assert tr.failed is None and tr.steps == len(stp), tr.failed
    return spent


def overhead(make, stp, rounds, cpu_limits):
    """(median bare step [us], median of the rounds' runner-minus-bare per step [us], the
    quartiles of those differences [us]) over interleaved rounds.

    Each round times the bare steps and the same steps through a fresh runner back to back,
    in alternating order (bare first, then runner first), so a drift of the machine's speed
    (another job starting, the CPU's clock) lands on both sides equally; each side starts
    from a freshly built filter (the same seed), so both do the very same work (the PF's
    resampling and its random draws included); the figure is the median of the rounds' own
    differences, which one disturbed round cannot move."""
    f = make()
    f.reset(None)
    bare(f, stp[:5])
    through_runner(f, stp[:5], cpu_limits)  # warm-up: first calls, the watchdog thread
    b, d = [], []

    def fresh():
        g = make()
        g.reset(None)
        return g

    for k in range(rounds):
        if k % 2 == 0:
            tb = bare(fresh(), stp)
            tr = through_runner(fresh(), stp, cpu_limits)
        else:
            tr = through_runner(fresh(), stp, cpu_limits)
            tb = bare(fresh(), stp)
        b.append(tb / len(stp) * 1e6)
        d.append((tr - tb) / len(stp) * 1e6)
    q1, _, q3 = statistics.quantiles(d, n=4)
    return statistics.median(b), statistics.median(d), (q1, q3)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer rounds")
    args = ap.parse_args()
    q = args.quick
    print(f"load average at start: {os.getloadavg()[0]:.2f}; CPU time, medians of interleaved rounds")
    sc, stp = krejsa("bearing", 1000)
    pf_steps = stp[:10 if q else 20]
    rows = [("trivial", Trivial, stp, 21 if q else 61),
            ("ekf", lambda: build_filter("ekf", sc, 0), stp, 21 if q else 61),
            ("pf 100k", lambda: build_filter("pf", sc, 0, params={"n_particles": 100_000}), pf_steps,
             9 if q else 15)]
    for cpu_limits in (False, True):
        mode = "CPU-time limit" if cpu_limits else "wall-time limit"
        for name, make, s, rounds in rows:
            step_us, extra_us, (q1, q3) = overhead(make, s, rounds, cpu_limits)
            print(f"{name:8s} ({mode}): bare step {step_us:9.1f} us, the runner adds {extra_us:6.2f} us "
                  f"({extra_us / step_us * 100:5.1f} %; quartiles of {rounds} rounds {q1:.2f}, {q3:.2f})")
            if name == "pf 100k":  # the target is the share (the step's own noise is larger than 3 us)
                figure(f"runner's own cost / pf 100k step, {mode} (CPU)", extra_us, "us",
                       peer="pf 100k bare step", peer_value=step_us, target=0.05, target_of="ratio")
            else:
                figure(f"runner's own cost per step, {name}, {mode} (CPU)", extra_us, "us",
                       peer=f"{name} bare step", peer_value=step_us, target=3.0)
    print(f"load average at end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
