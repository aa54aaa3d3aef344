"""Dask's CPU against local processes: the same ``eval`` runs on 2 local processes
and on a Dask LocalCluster of 2 worker processes x 1 thread, CPU time of every process
(this one, which holds the scheduler, the nannies and the client; the workers; the local
pool's children), interleaved rounds, medians, results compared bit for bit.

Run:  python benchmarks/bench_dask.py [--quick] [--runs N] [--duration S] [--rounds K]
      [--dask-defaults]

What the extra goes to is measured beside it: the cluster's idle CPU per second (its event
loops, heartbeats, monitors and the workers' sampling profiler, with no task), times the
round's wall time, and what is left (per-task scheduling and serialisation). The cluster
runs with the settings docs/performance.md recommends for eval workers (the workers'
sampling profiler off, the admin tick and the monitors slower: ``DASK_LEAN_CONFIG`` in
evaluation/montecarlo.py) unless ``--dask-defaults``. The runs are the per-run path
(``batch=False``: a task per group of runs, ``TASKS_PER_DASK_WORKER`` tasks a worker) and
the batched path (one batch per worker).
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import time

import numpy as np
from figures import figure, proc_cpu

from beacon_sim.core.scenario import load_scenario
from beacon_sim.evaluation.montecarlo import DASK_LEAN_CONFIG, run_monte_carlo

#: The Dask settings docs/performance.md recommends for eval workers.
LEAN = DASK_LEAN_CONFIG


def self_cpu() -> float:
    """CPU time [s] of this process (all its threads)."""
    u = resource.getrusage(resource.RUSAGE_SELF)
    return u.ru_utime + u.ru_stime


def children_cpu() -> float:
    """CPU time [s] of the reaped child processes (a finished local pool)."""
    u = resource.getrusage(resource.RUSAGE_CHILDREN)
    return u.ru_utime + u.ru_stime


def same(a, b) -> bool:
    """Whether two lists of runs hold the same figures bit for bit."""
    for ra, rb in zip(a, b, strict=True):
        if ra.seed != rb.seed or not np.array_equal(ra.truth, rb.truth):
            return False
        for name, fa in ra.filters.items():
            fb = rb.filters[name]
            arrays = (("err", "var", "nees"))
            if fa.failed != fb.failed or not all(
                    np.array_equal(getattr(fa, k), getattr(fb, k), equal_nan=True) for k in arrays):
                return False
    return len(a) == len(b)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer runs and rounds")
    ap.add_argument("--runs", type=int, default=None)
    ap.add_argument("--duration", type=float, default=None, help="simulated seconds a run")
    ap.add_argument("--rounds", type=int, default=None)
    ap.add_argument("--dask-defaults", action="store_true", help="Dask's own settings, not LEAN")
    args = ap.parse_args()
    q = args.quick
    runs = args.runs or (20 if q else 40)
    duration = args.duration or (30.0 if q else 60.0)
    rounds = args.rounds or (3 if q else 5)

    import dask
    from dask.distributed import Client, LocalCluster

    if not args.dask_defaults:
        dask.config.set(LEAN)
    sc = load_scenario("default")
    specs = ["ekf", "ukf", "pf"]
    load0 = os.getloadavg()[0]
    print(f"load average at start: {load0:.2f}; {runs} runs x {duration:g} s of `default`, "
          f"filters {', '.join(specs)}; Dask settings: {'defaults' if args.dask_defaults else LEAN}")
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        pids = sorted({*client.run(os.getpid).values()} - {os.getpid()})
        # idle: what the cluster costs a second with nothing to do, its workers and this process
        c0, s0, w0 = proc_cpu(pids), self_cpu(), time.perf_counter()
        time.sleep(3.0 if q else 6.0)
        w = time.perf_counter() - w0
        idle_workers, idle_main = (proc_cpu(pids) - c0) / w, (self_cpu() - s0) / w
        idle_rate = idle_workers + idle_main
        print(f"the idle cluster: {idle_rate * 1e3:.1f} ms CPU a second (workers {idle_workers * 1e3:.1f}, "
              f"this process's scheduler, nannies and client {idle_main * 1e3:.1f})")
        figure("Dask LocalCluster (2 workers) idle CPU", idle_rate * 1e3, "ms/s")
        for batch, label in ((False, "per-run path"), (None, "batched path")):
            got_rounds: dict[str, list[float]] = {k: [] for k in ("lw", "lm", "dw", "dm", "wall", "ratio")}
            ok = True
            for k in range(rounds + 1):  # the first round warms up (imports on the workers)
                s0, k0 = self_cpu(), children_cpu()
                ref = run_monte_carlo(sc, specs, runs, seed=3, duration=duration, jobs=2, progress=False,
                                      batch=batch)
                lm, lw = self_cpu() - s0, children_cpu() - k0
                c0, s0, w0 = proc_cpu(pids), self_cpu(), time.perf_counter()
                got = run_monte_carlo(sc, specs, runs, seed=3, duration=duration, progress=False,
                                      batch=batch, scheduler=client)
                dw, dm, wall = proc_cpu(pids) - c0, self_cpu() - s0, time.perf_counter() - w0
                ok = ok and same(ref, got)
                if k:
                    for key, v in (("lw", lw), ("lm", lm), ("dw", dw), ("dm", dm), ("wall", wall),
                                   ("ratio", (dw + dm) / (lw + lm))):
                        got_rounds[key].append(v)
            med = {key: statistics.median(v) for key, v in got_rounds.items()}
            local, dask = med["lw"] + med["lm"], med["dw"] + med["dm"]
            each = ", ".join(f"{r:.3f}" for r in got_rounds["ratio"])
            print(f"{label}: local {local:.2f} s CPU, Dask {dask:.2f} s CPU: {med['ratio']:.3f}x (the median "
                  f"of {rounds} interleaved rounds' ratios: {each}); results "
                  f"{'the same bit for bit' if ok else 'DIFFER'}")
            extra_w = med["dw"] - med["lw"]
            print(f"  workers: local {med['lw']:.2f} s, Dask {med['dw']:.2f} s ({extra_w:+.2f}; "
                  f"idle they cost {idle_workers * med['wall']:.2f} s in the {med['wall']:.1f} s); "
                  f"the main process: local {med['lm']:.2f} s, Dask (scheduler, nannies, client, "
                  f"serialisation) {med['dm']:.2f} s ({med['dm'] - med['lm']:+.2f}; idle "
                  f"{idle_main * med['wall']:.2f} s)")
            figure(f"eval on Dask / local processes, CPU, {label} ({runs} runs)", med["ratio"], "x",
                   target=1.10)
            assert ok, "Dask's results differ from the local ones"
    print(f"load average at end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
