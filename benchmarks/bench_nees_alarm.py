"""The NEES badge's false-alarm rate on a consistent filter: the EKF on ``default`` (its
driver, the scenario's noise, the filter told the true models) over an hour of simulated
driving, the windowed verdict the panel shows against the per-tick band it replaced; and
with ``--standstill N`` the badge over a minute's pause (the robot still from t = 0, the
window's session) on N unseen seeds, of the EKF and the PF on default, two_rooms and
assignment_kf.

    python benchmarks/bench_nees_alarm.py [--hours 1] [--seeds 7 8] [--standstill 20]

Targets: a few alarms per hour (a lecture) at most; a badge in at most 1 of 20 pauses.
"""

from __future__ import annotations

import argparse
import os
import time

from beacon_sim.core.scenario import load_scenario
from beacon_sim.runs.nees_alarm import count_alarms, count_standstill_badges

#: The unseen seeds of the standstill rows (docs/results.md's range).
FIRST_SEED = 20000


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=1.0)
    ap.add_argument("--seeds", type=int, nargs="+", default=[7])
    ap.add_argument("--scenario", default="default")
    ap.add_argument("--filter", default="ekf")
    ap.add_argument("--standstill", type=int, default=0, metavar="N",
                    help="also N seeds of a minute's standstill per scenario and filter")
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
    if a.standstill:
        seeds = range(FIRST_SEED, FIRST_SEED + a.standstill)
        print(f"\na minute's standstill from t = 0, seeds {seeds.start}..{seeds.stop - 1}; "
              "the badge once the 20 s window is full")
        print("| scenario | filter | seeds with a badge | ticks high | ticks low | ticks judged | verdict |")
        print("|---|---|---|---|---|---|---|")
        for name in ("default", "two_rooms", "assignment_kf"):
            for spec in ("ekf", "pf"):
                c = count_standstill_badges(load_scenario(name), spec, seeds, 60.0)
                verdict = "met" if c.flagged <= max(1, c.seeds // 20) else "NOT met"
                print(f"| {name} | {spec} | {c.flagged}/{c.seeds} | {c.high} | {c.low} | {c.ticks} | "
                      f"{verdict} |")


if __name__ == "__main__":
    main()
