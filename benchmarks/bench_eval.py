"""Wall time of a Monte Carlo evaluation: 100 runs x 2,000 steps x the Gaussian filters
(kf, ekf, ukf) on `default`, in parallel processes (target: 5 s with 2 jobs at
load < 2), with the CPU time of the workers beside it and the load average.

The filters run batched across runs (each filter's batched form, driven by
evaluation.montecarlo.batch_runs on the tick's arrays from core.batch_simulation; the
default). The per-run path (``--no-batch``) is timed in the same session on
``--per-run-runs`` runs and scaled up to ``--runs``: the peer. Also prints where one
worker's time goes, in CPU per run-step: the batched simulation (``advance``), the packing
of the readings, each batched filter (with the NIS it does not give itself), and the
single-run simulation for comparison; the floor ``(simulation + filters) x steps x runs /
jobs`` against the wall time. Best of ``--repeat`` tries (the least disturbed).
Usage: python benchmarks/bench_eval.py [--runs N] [--steps N] [--jobs J] [--per-run-runs N]
       [--repeat K]
"""

from __future__ import annotations

import argparse
import os
import resource
import time

import numpy as np
from figures import figure

from beacon_sim.core.batch_simulation import BatchSimulation
from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.evaluation.montecarlo import default_jobs, run_monte_carlo
from beacon_sim.filters.gaussian.measurements import SlotPacker, nis
from beacon_sim.hosting.loading import available_filters, build_filter

TARGET_S = 5.0


def children_cpu() -> float:
    """CPU time [s] of the finished child processes (the eval workers) so far."""
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def timed_eval(sc, filters, runs, duration, jobs, batch) -> tuple[float, float]:
    """Wall time and CPU time (this process and its workers) [s] of one evaluation."""
    c0, k0, w0 = time.process_time(), children_cpu(), time.perf_counter()
    run_monte_carlo(sc, filters, runs, seed=0, duration=duration, jobs=jobs, progress=False, batch=batch)
    wall = time.perf_counter() - w0
    return wall, time.process_time() - c0 + children_cpu() - k0


def worker_parts(sc, filters, runs, steps) -> dict[str, float]:
    """CPU time per run-step [us] of each part of one batched worker (``runs`` runs)."""
    pc = time.process_time
    bs = BatchSimulation(sc, list(range(runs)), readings_checksums=False)
    packer = SlotPacker(sc.world, sc.model_sensors)
    batched = {n: build_filter(n, sc, 0, name=n).batched(runs) for n in filters}
    parts = dict.fromkeys(["simulation (batched)", "packing", *filters], 0.0)
    with np.errstate(all="ignore"):
        for _ in range(steps):
            t0 = pc()
            tick = bs.advance()
            t1 = pc()
            st = packer.pack_tick(tick)
            parts["simulation (batched)"] += t1 - t0
            parts["packing"] += pc() - t1
            for n, f in batched.items():
                t0 = pc()
                f.predict(tick.v, tick.omega, tick.dt)
                if st is not None:
                    if not f.own_nis:
                        nis(f.mean, f.cov, st)
                    f.update(st)
                parts[n] += pc() - t0
    return {k: v / (steps * runs) * 1e6 for k, v in parts.items()}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--jobs", type=int, default=min(2, default_jobs()))
    ap.add_argument("--per-run-runs", type=int, default=20,
                    help="runs for the per-run (unbatched) comparison, scaled up (0: skip)")
    ap.add_argument("--repeat", type=int, default=2, help="tries of the batched eval (the best counts)")
    args = ap.parse_args()
    sc = load_scenario("default")
    filters = [f for f in ("kf", "ekf", "ukf") if f in available_filters()]
    duration = args.steps * sc.dt
    load0 = os.getloadavg()[0]

    sim = Simulation(sc, 0)
    t = time.process_time()
    for _ in range(2000):
        sim.step()
    sim_us = (time.process_time() - t) / 2000 * 1e6

    tries = [timed_eval(sc, filters, args.runs, duration, args.jobs, None) for _ in range(args.repeat)]
    wall, cpu = min(tries)
    load = os.getloadavg()[0]
    per_run = None
    if args.per_run_runs > 0:
        w, c = timed_eval(sc, filters, args.per_run_runs, duration, args.jobs, False)
        per_run = (w * args.runs / args.per_run_runs, c * args.runs / args.per_run_runs)
    per_worker = -(-args.runs // args.jobs)
    parts = worker_parts(sc, filters, min(per_worker, 50), min(args.steps, 1000))
    floor = sum(parts.values()) * args.steps * args.runs / 1e6 / args.jobs
    total = args.runs * args.steps * len(filters)
    print(f"load average {load0:.2f} at start, {load:.2f} after the batched eval, "
          f"{os.getloadavg()[0]:.2f} at end")
    print(f"{'figure':<48}{'wall':>9}{'CPU':>9}  unit")
    print(f"{'eval (batched)':<48}{wall:>9.2f}{cpu:>9.2f}  s ({args.runs} runs x {args.steps} steps x "
          f"{len(filters)} filters: {', '.join(filters)}; {args.jobs} jobs; best of {args.repeat}: "
          + ", ".join(f"{w:.2f}" for w, _ in tries) + ")")
    print(f"{'filter steps per second':<48}{total / wall:>9.0f}{'':>9}  1/s")
    print(f"{'target (wall, at load < 2)':<48}{TARGET_S:>9.2f}{'':>9}  s")
    print(f"{'wall / target':<48}{wall / TARGET_S:>9.2f}{'':>9}  ratio")
    if per_run is not None:
        label = f"per-run path ({args.per_run_runs} runs, scaled)"
        print(f"{label:<48}{per_run[0]:>9.2f}{per_run[1]:>9.2f}  s")
        print(f"{'batched / per-run':<48}{wall / per_run[0]:>9.2f}{cpu / per_run[1]:>9.2f}  ratio")
    print(f"one worker's CPU per run-step ({min(per_worker, 50)} runs):")
    for k, us in parts.items():
        print(f"{'  ' + k:<48}{'':>9}{us:>9.2f}  us")
    print(f"{'  simulation (single run, for comparison)':<48}{'':>9}{sim_us:>9.2f}  us")
    print(f"{'floor: worker CPU x steps x runs / jobs':<48}{floor:>9.2f}{'':>9}  s")
    print(f"{'wall / floor (start-up, summary, waiting)':<48}{wall / floor:>9.2f}{'':>9}  ratio")
    what = f"eval {args.runs} runs x {args.steps} steps x {len(filters)} filters, {args.jobs} jobs"
    figure(what, wall, "s", peer="per-run path" if per_run is not None else None,
           peer_value=per_run[0] if per_run is not None else None, target=TARGET_S, cpu=cpu)
    figure("eval worker, simulation per run-step (batched)", parts["simulation (batched)"], "us",
           peer="single-run simulation", peer_value=sim_us, cpu=parts["simulation (batched)"])


if __name__ == "__main__":
    main()
