"""The EKF's and the UKF's step cost by the number of readings in view.

Run:  python benchmarks/bench_readings.py [--rounds 5] [--seconds 1.0]

`default`'s room and tour with n beacons, all in view and seen on every tick (range-bearing,
``bench_goals.beacon_scenario``), n = 1, 10, 100, 1000. Each round times the EKF and then the
UKF over the same recorded ticks (predict + update, process CPU time, per step); the FIGURE
line's ratio is the EKF's median over the rounds against the UKF's, the table's last column
the median of each round's own ratio (the two agree to a few %). Target: <= 1.0 at every n
(the EKF no slower than the UKF). Above ``ekf.STACKED_ROWS`` rows a tick the EKF takes its
stacked form on arrays, below it the row-by-row form on floats.
"""

from __future__ import annotations

import argparse
import os
import statistics

from bench_goals import beacon_scenario
from figures import Clock, figure

from beacon_sim.core.simulation import Simulation
from beacon_sim.hosting.loading import build_filter

COUNTS = (1, 10, 100, 1000)


def step_cpu(spec, sc, steps) -> float:
    """CPU per step [us] of predict + update over ``steps``, from a fresh filter."""
    f = build_filter(spec, sc, 0)
    with Clock() as c:
        for st in steps:
            f.predict(st.control, st.dt)
            f.update(st.measurements)
    return c.cpu / len(steps) * 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--seconds", type=float, default=1.0, help="simulated time per round")
    args = ap.parse_args()
    print(f"load average at start: {os.getloadavg()[0]:.2f}; CPU us per step, median of "
          f"{args.rounds} rounds")
    print(f"{'in view':>8}{'ekf':>10}{'ukf':>10}{'ekf/ukf':>9}")
    for n in COUNTS:
        sc = beacon_scenario(n, n)
        steps = Simulation(sc, 0).run(args.seconds)
        step_cpu("ekf", sc, steps[:5])   # warm-up (imports, caches)
        step_cpu("ukf", sc, steps[:5])
        e, u, r = [], [], []
        for _ in range(args.rounds):
            e.append(step_cpu("ekf", sc, steps))
            u.append(step_cpu("ukf", sc, steps))
            r.append(e[-1] / u[-1])
        em, um, rm = statistics.median(e), statistics.median(u), statistics.median(r)
        print(f"{n:>8}{em:>10.1f}{um:>10.1f}{rm:>8.2f}x")
        figure(f"ekf / ukf step, {n} range-bearing readings in view (CPU)", em, "us", peer="our ukf",
               peer_value=um, target=1.0, target_of="ratio")
    print(f"load average at end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
