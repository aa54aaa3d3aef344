"""Soak test: every built-in filter over a long run with random driving, frequent
kidnaps and resets, checking after every step that each estimate is finite with a symmetric
positive semi-definite covariance (the runner's own guard, ``validate_estimate``).

    python benchmarks/soak.py [--steps 1000000] [--scenario default] [--seed 0]

Prints progress every 10 % and a summary: steps, wall time, failures per filter (with the
tick and reason of the first). Exit status 1 when any filter failed. The particle filter
runs with 300 particles and the grid with 0.5 m cells so that 10^6 steps take minutes.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import Counter
from dataclasses import replace

import numpy as np

from beacon_sim.core.drivers import RandomGoalSpec
from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.hosting.loading import BUILTIN_FILTERS, build_filter, reset_filter
from beacon_sim.hosting.runner import HEADLESS_STEP_LIMIT_S, FilterRunner, validate_estimate

PARAMS = {"pf": {"n_particles": 300}, "histogram": {"cell": 0.5}}
KIDNAP_EVERY = 700      # ticks between kidnaps (random pose), on average
RESET_EVERY = 400       # ticks between resets of every filter (R), on average
GLOBAL_EVERY = 2500     # ticks between global resets (G), on average


def soak(steps: int, scenario_name: str, seed: int) -> int:
    sc = load_scenario(scenario_name)
    sc = replace(sc, driver=RandomGoalSpec(speed=0.4))  # random driving, whatever the file says
    rng = np.random.default_rng(seed)
    names = list(BUILTIN_FILTERS)
    filters = {n: build_filter(n, sc, seed, params=PARAMS.get(n)) for n in names}
    runner = FilterRunner(filters, step_limit_s=HEADLESS_STEP_LIMIT_S, keep=1)
    sim = Simulation(sc, seed)
    failures: Counter[str] = Counter()
    first: dict[str, str] = {}
    kidnaps = resets = 0
    t0 = time.perf_counter()
    for k in range(1, steps + 1):
        if rng.random() < 1 / KIDNAP_EVERY:
            sim.request_kidnap(None)
            kidnaps += 1
        if rng.random() < 1 / RESET_EVERY:
            for f in filters.values():
                reset_filter(f, sc)
            resets += 1
        if rng.random() < 1 / GLOBAL_EVERY:
            for f in filters.values():
                if getattr(f, "supports_global", False):
                    f.reset(None)
            resets += 1
        runner.feed(sim.step())
        for name, tr in runner.tracks.items():
            why = tr.failed
            if why is None:
                checked = validate_estimate((tr.means[-1], tr.covs[-1]))
                why = checked if isinstance(checked, str) else None
            if why is not None:  # count it, then start the filter again from the initial belief
                failures[name] += 1
                first.setdefault(name, f"tick {k}: {why}")
                f = build_filter(name, sc, seed + k, params=PARAMS.get(name))
                filters[name] = f
                runner.tracks[name] = FilterRunner({name: f}, step_limit_s=HEADLESS_STEP_LIMIT_S,
                                                   keep=1).tracks[name]
        if k % max(1, steps // 10) == 0:
            print(f"  {k:,} steps, {time.perf_counter() - t0:.0f} s, failures {sum(failures.values())}",
                  file=sys.stderr, flush=True)
    wall = time.perf_counter() - t0
    print(f"soak {sc.name}: {steps:,} steps ({steps * sc.dt / 3600:.1f} h simulated) in {wall:.0f} s, "
          f"{kidnaps} kidnaps, {resets} resets, filters {', '.join(names)}")
    for name in names:
        tr = runner.tracks[name]
        print(f"  {name:<15} failures {failures[name]:>4}  {tr.us_per_step:8.1f} us/step"
              + (f"  first: {first[name]}" if name in first else ""))
    return 1 if failures else 0


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=int, default=1_000_000)
    p.add_argument("--scenario", default="default")
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args()
    return soak(a.steps, a.scenario, a.seed)


if __name__ == "__main__":
    raise SystemExit(main())
