"""Print the smoothing figure: the EKF and its Rauch-Tung-Striebel smoother on ``default``
over 50 seeds the tests and the tuning never used (1000..1049 by default), against the
truth, the filtering bound (PCRB) and the smoothing bound, with 95 % bootstrap intervals.
docs/results.md's is made by ``python scripts/make_results.py --only smoothing`` (seeds
20000..20049).

Usage: python scripts/smoothing_results.py [--runs N] [--first-seed S] [--filter ekf|ukf]
(the same as ``beacon-sim eval default --filter ekf --runs 50 --seed 1000 --smooth``).
"""

from __future__ import annotations

import argparse
import time

from beacon_sim.core.scenario import load_any_scenario
from beacon_sim.evaluation.intervals import text
from beacon_sim.evaluation.smoothing_run import smoothing_monte_carlo


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=50)
    ap.add_argument("--first-seed", type=int, default=1000)
    ap.add_argument("--filter", default="ekf")
    args = ap.parse_args()
    sc = load_any_scenario("default").robots[0].scenario
    t0 = time.process_time()
    f = smoothing_monte_carlo(sc, args.filter, range(args.first_seed, args.first_seed + args.runs))
    print(f"{args.filter} on default, {f['runs']} runs x {f['ticks'] // f['runs']} ticks, seeds "
          f"{args.first_seed}..{args.first_seed + args.runs - 1} ({time.process_time() - t0:.0f} s of CPU)")
    print("| estimate | pos RMSE [m] | heading RMSE [rad] | ANEES | bound pos RMSE [m] | RMSE / bound |")
    print("|---|---|---|---|---|---|")
    for label, bound in (("filtered", "filtering PCRB"), ("smoothed", "smoothing bound")):
        r = f[label]
        print(f"| {args.filter} {label} | {r['pos_rmse_m']:.4f} {text(r['pos_rmse_m_ci'], '.4f')} | "
              f"{r['heading_rmse_rad']:.4f} | {r['anees']:.2f} {text(r['anees_ci'], '.2f')} | "
              f"{r['bound_pos_rmse_m']:.4f} ({bound}) | {r['pos_rmse_over_bound']:.3f} "
              f"{text(r['pos_rmse_over_bound_ci'], '.3f')} |")
    lo, hi = f["anees_band"]
    print(f"ANEES 95 % band of one run's ticks, 3 dof: [{lo:.2f}, {hi:.2f}]")


if __name__ == "__main__":
    main()
