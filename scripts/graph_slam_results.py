"""Print docs/smoothing.md's graph SLAM table: graph SLAM (Gauss-Newton over the whole drive)
against EKF-SLAM and odometry on ``slam_loop``, ATE at the graph's pose ticks pooled over
runs with 95 % bootstrap intervals, and the map's GOSPA (1 m cut-off).

Usage: python scripts/graph_slam_results.py [--runs N] [--first-seed S] [--scenario NAME]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from beacon_sim.core.scenario import load_any_scenario
from beacon_sim.evaluation.graph_slam_run import PEER, ate_table
from beacon_sim.evaluation.intervals import text

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results.common import DOCS_SEED  # the docs' seeds, as make_results has them


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--first-seed", type=int, default=DOCS_SEED,
                    help="the first seed (default: the docs' seeds, which no test or tuning uses)")
    ap.add_argument("--scenario", default="slam_loop")
    args = ap.parse_args()
    sc = load_any_scenario(args.scenario).robots[0].scenario
    t0 = time.process_time()
    t = ate_table(sc, range(args.first_seed, args.first_seed + args.runs))
    print(f"{args.scenario}, {t['runs']} runs, seeds {args.first_seed}..{args.first_seed + args.runs - 1} "
          f"({time.process_time() - t0:.0f} s of CPU)")
    print("| estimate | ATE [m] | map GOSPA [m] |")
    print("|---|---|---|")
    for key, label in (("graph", "graph SLAM (Gauss-Newton)"), (PEER, "EKF-SLAM"), ("odometry", "odometry")):
        r = t[key]
        gospa = f"{r['map_gospa_m']:.3f}" if "map_gospa_m" in r else "-"
        print(f"| {label} | {r['ate_m']:.3f} {text(r['ate_m_ci'], '.3f')} | {gospa} |")


if __name__ == "__main__":
    main()
