"""Cost of the range finder's maths on an occupancy grid (against its speed targets).

Run:  .venv/bin/python benchmarks/bench_raycast.py [--quick]

- one 180-beam scan (full circle, 10 m max range) ray cast on a 400 x 400 grid at 0.05 m
  (a 20 m x 20 m floor with outer walls and 60 random pillars);  target <= 1 ms;
- the beam model's expected ranges for 1,000 particles x 60 beams (60,000 rays, what a
  particle filter with the beam model casts per update); no target, shown beside the
  likelihood field it is the reason AMCL users pick the field;
- the likelihood-field log-likelihood of 10,000 particles x 60 beams (all below max range) on
  the same map (float32 end points, the fast path; float64 shown beside it);  target <= 5 ms.

Each figure is the median over rounds of wall time, with the median CPU time of the same
rounds beside it (other jobs on a shared machine inflate the wall time, not the CPU time).
The map and particles are seeded, so every run measures the same work.
"""

from __future__ import annotations

import argparse

import numpy as np
from figures import figure, median_ms

from beacon_sim.core.beam_model import LikelihoodField, RangeModelParams
from beacon_sim.core.occupancy import FREE, OCCUPIED, OccupancyGrid
from beacon_sim.core.raycast import beam_angles, expected_ranges, scan

MAX_RANGE = 10.0


def floor_map(seed: int = 0) -> OccupancyGrid:
    """400 x 400 cells at 0.05 m: outer walls and 60 random 0.25 m x 1 m pillars."""
    rng = np.random.default_rng(seed)
    cells = np.full((400, 400), FREE, dtype=np.int8)
    cells[:2, :] = cells[-2:, :] = cells[:, :2] = cells[:, -2:] = OCCUPIED
    for _ in range(60):
        r, c = rng.integers(10, 380, size=2)
        if rng.random() < 0.5:
            cells[r:r + 20, c:c + 5] = OCCUPIED
        else:
            cells[r:r + 5, c:c + 20] = OCCUPIED
    cells[190:210, 190:210] = FREE  # the robot's spot is clear
    return OccupancyGrid(cells, 0.05, (0.0, 0.0, 0.0))



def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer rounds")
    args = ap.parse_args()
    n = 20 if args.quick else 200
    grid = floor_map()
    pose = (10.0, 10.0, 0.3)

    scan_ms, scan_cpu = median_ms(lambda: scan(grid, pose, 180, 2 * np.pi, MAX_RANGE), n)
    # The field's scan uses a 30 m sensor so that all 60 beams end on a wall (a reading at max
    # range is skipped, and would make the figure cheaper than its name says).
    rel, ranges = scan(grid, pose, 60, 2 * np.pi, 30.0)
    assert np.all(ranges < 30.0)
    field = LikelihoodField(grid, RangeModelParams(laser_max_range=30.0))
    rng = np.random.default_rng(1)
    particles = np.column_stack([rng.uniform(0.5, 19.5, 10_000), rng.uniform(0.5, 19.5, 10_000),
                                 rng.uniform(-np.pi, np.pi, 10_000)])
    n_lf = max(10, n // 4)
    beams60 = beam_angles(60, 2 * np.pi)
    beam_ms, beam_cpu = median_ms(lambda: expected_ranges(grid, particles[:1000], beams60, MAX_RANGE),
                               max(3, n // 40))
    lf32, lf32_cpu = median_ms(lambda: field.log_likelihood(particles, ranges, rel, dtype=np.float32), n_lf)
    lf64, lf64_cpu = median_ms(lambda: field.log_likelihood(particles, ranges, rel, dtype=np.float64), n_lf)

    table = [("ray cast, one 180-beam scan, 400x400 grid, 10 m", scan_ms, scan_cpu, "1"),
             ("beam model: ray cast 1k particles x 60 beams, 10 m", beam_ms, beam_cpu, "-"),
             ("likelihood field, 10k particles x 60 beams, float32", lf32, lf32_cpu, "5"),
             ("likelihood field, 10k particles x 60 beams, float64", lf64, lf64_cpu, "-")]
    print(f"{'what':58s} {'wall ms':>8s} {'cpu ms':>8s} {'target':>7s}")
    for what, wall, cpu, target in table:
        print(f"{what:58s} {wall:8.3f} {cpu:8.3f} {target:>7s}")
    figure("ray cast, one 180-beam scan on a 400x400 grid (10 m range)", scan_ms, "ms",
           target=1.0, cpu=scan_cpu)
    figure("beam model: ray cast of 1k particles x 60 beams (10 m)", beam_ms, "ms", cpu=beam_cpu)
    figure("likelihood field, 10k particles x 60 beams (float32)", lf32, "ms", target=5.0, cpu=lf32_cpu)
    figure("likelihood field, 10k particles x 60 beams (float64)", lf64, "ms", cpu=lf64_cpu)


if __name__ == "__main__":
    main()
