"""The NEES badge's false-alarm rate on a consistent filter: the EKF on ``default`` (its
driver, the scenario's noise, the filter told the true models) over an hour of simulated
driving, the windowed verdict the panel shows against the per-tick band it replaced.

    python benchmarks/bench_nees_alarm.py [--hours 1] [--seeds 7 8]

Target: a few alarms per hour (a lecture) at most.
"""

from __future__ import annotations

import argparse
import os
import time

from beacon_sim.core.scenario import load_scenario
from beacon_sim.runs.nees_alarm import count_alarms


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=1.0)
    ap.add_argument("--seeds", type=int, nargs="+", default=[7])
    ap.add_argument("--scenario", default="default")
    ap.add_argument("--filter", default="ekf")
    a = ap.parse_args()
    sc = load_scenario(a.scenario)
    print(f"load average {os.getloadavg()[0]:.1f}; {a.filter} on {a.scenario}, {a.hours:g} h per seed")
    for seed in a.seeds:
        t0 = time.perf_counter()
        c = count_alarms(sc, a.filter, seed, a.hours * 3600.0)
        verdict = "met" if c.per_hour <= 3.0 else "NOT met"
        print(f"seed {seed}: windowed badge {c.windowed} ({c.high} high, {c.low} low) = "
              f"{c.per_hour:.1f} per hour [{verdict}, target <= 3]; per-tick badge {c.per_tick} "
              f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
