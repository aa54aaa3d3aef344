"""Wall time of a Monte Carlo evaluation: 100 runs x 2,000 steps x the Gaussian filters
(kf, ekf, ukf) on `default`, in parallel processes on all cores (issue 16's target: 5 s
with 2 jobs at load < 2).

The filters run batched across runs (each filter's batched form, driven by
evaluation.montecarlo.batch_runs; the default). The per-run path (``--no-batch``) is timed
in the same session on ``--per-run-runs`` runs and
scaled up to ``--runs``. Also prints where the time goes: the bare simulation per step,
each filter's cost per run-step, and the floor ``(simulation + filters) x steps x runs /
jobs``.
Usage: python benchmarks/bench_eval.py [--runs N] [--steps N] [--jobs J] [--per-run-runs N]
"""

from __future__ import annotations

import argparse
import time

from figures import figure

from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.evaluation.montecarlo import default_jobs, run_monte_carlo
from beacon_sim.filters.loading import available_filters

TARGET_S = 5.0


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--jobs", type=int, default=default_jobs())
    ap.add_argument("--per-run-runs", type=int, default=20,
                    help="runs for the per-run (unbatched) comparison, scaled up (0: skip)")
    args = ap.parse_args()
    sc = load_scenario("default")
    filters = [f for f in ("kf", "ekf", "ukf") if f in available_filters()]
    duration = args.steps * sc.dt

    sim = Simulation(sc, 0)
    t = time.perf_counter()
    for _ in range(2000):
        sim.step()
    sim_us = (time.perf_counter() - t) / 2000 * 1e6

    t = time.perf_counter()
    runs = run_monte_carlo(sc, filters, args.runs, seed=0, duration=duration, jobs=args.jobs,
                           progress=False)
    wall = time.perf_counter() - t
    per_run_wall = None
    if args.per_run_runs > 0:
        t = time.perf_counter()
        run_monte_carlo(sc, filters, args.per_run_runs, seed=0, duration=duration, jobs=args.jobs,
                        progress=False, batch=False)
        per_run_wall = (time.perf_counter() - t) * args.runs / args.per_run_runs
    per_filter = {n: sum(r.filters[n].step_ns for r in runs) / sum(r.filters[n].steps for r in runs) / 1e3
                  for n in runs[0].filters}
    floor = (sim_us + sum(per_filter.values())) * args.steps * args.runs / 1e6 / args.jobs
    total = args.runs * args.steps * len(filters)
    print(f"{'figure':<44}{'value':>12}  unit")
    print(f"{'eval wall time':<44}{wall:>12.2f}  s ({args.runs} runs x {args.steps} steps x "
          f"{len(filters)} filters: {', '.join(filters)}; {args.jobs} jobs)")
    print(f"{'filter steps per second':<44}{total / wall:>12.0f}  1/s")
    print(f"{'(peer) target':<44}{TARGET_S:>12.2f}  s")
    print(f"{'wall / target':<44}{wall / TARGET_S:>12.2f}  ratio")
    if per_run_wall is not None:
        label = f"per-run path ({args.per_run_runs} runs, scaled)"
        print(f"{label:<44}{per_run_wall:>12.2f}  s")
        print(f"{'per-run / batched':<44}{per_run_wall / wall:>12.2f}  ratio")
    print(f"{'simulation step':<44}{sim_us:>12.1f}  us")
    for n, us in per_filter.items():
        print(f"{n + ' step (batched, per run-step)':<44}{us:>12.1f}  us")
    print(f"{'floor: (sim + filters) x steps x runs / jobs':<44}{floor:>12.2f}  s")
    print(f"{'wall / floor (evaluation overhead)':<44}{wall / floor:>12.2f}  ratio")
    figure(f"eval {args.runs} runs x {args.steps} steps x {len(filters)} filters", wall, "s",
           peer="per-run path" if per_run_wall is not None else None, peer_value=per_run_wall,
           target=TARGET_S)
    figure("simulation step (default)", sim_us, "us")


if __name__ == "__main__":
    main()
