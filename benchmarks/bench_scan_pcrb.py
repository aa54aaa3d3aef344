"""Cost of the PCRB in map worlds: the bound of 8 runs x 60 s of each shipped map
scenario, its range finder's every scan ray cast and differentiated (core/scan_jacobian.py).

Run:  .venv/bin/python benchmarks/bench_scan_pcrb.py [--quick]

No target: the bound is computed once per evaluation (beside the runs, which cost far more
with mcl) and one tick at a time in the window. Each figure is the CPU and wall time of one
``pcrb`` call on seeded truths (the simulation is not timed), and per scan.
"""

from __future__ import annotations

import argparse

import numpy as np
from figures import Clock, figure

from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.evaluation.pcrb import pcrb


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="2 runs x 20 s")
    args = ap.parse_args()
    runs, seconds = (2, 20.0) if args.quick else (8, 60.0)
    for name in ("office", "corridor", "symmetric_room"):
        sc = load_scenario(name)
        truths, controls = [], []
        for seed in range(runs):
            steps = Simulation(sc, seed).run(seconds)
            truths.append([sc.initial_pose] + [s.true_pose for s in steps])
            controls.append([[s.control.v, s.control.omega] for s in steps])
        with Clock() as c:
            P = pcrb(sc, np.array(truths), np.array(controls))
        laser = next(s for s in sc.sensors if s.kind == "range_finder")
        scans = runs * seconds / laser.period
        bound_mm = 1e3 * float(np.sqrt(np.mean(P[:, -1, 0, 0] + P[:, -1, 1, 1])))
        print(f"{name}: {runs} runs x {seconds:.0f} s, {scans:.0f} scans of {laser.n_beams} beams: "
              f"{c.cpu:.2f} s CPU ({c.wall:.2f} s wall), {1e3 * c.cpu / scans:.2f} ms CPU per scan; "
              f"bound at the end {bound_mm:.1f} mm")
        figure(f"PCRB per scan, {name} ({laser.n_beams} beams)", 1e3 * c.wall / scans, "ms",
               cpu=1e3 * c.cpu / scans)


if __name__ == "__main__":
    main()
