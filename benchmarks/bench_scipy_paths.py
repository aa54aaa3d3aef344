"""The scipy paths (the ``science`` extra) against the numpy paths they stand in for.

- the exact Euclidean distance transform (``core.beam_model``): a 2000 x 2000 map with a few
  walls (sparse: numpy's second pass runs many offsets) and with 2 % occupied cells;
- the minimum-cost assignment (``evaluation.slam_metrics``, GOSPA's pairing) of random
  N x N costs.
Each line: numpy's time, scipy's, and the ratio (numpy / scipy), best of ``--repeat``, both
measured in this process; the results are checked equal. scipy's import is not timed.
Usage: python benchmarks/bench_scipy_paths.py [--repeat K]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import scipy.ndimage  # imported before any timing
import scipy.optimize  # noqa: F401

from beacon_sim.core import beam_model
from beacon_sim.core.beam_model import distance_transform, distance_transform_numpy
from beacon_sim.evaluation.slam_metrics import min_cost_assignment, min_cost_assignment_numpy


def best(fn, repeat: int) -> tuple[float, object]:
    out, t_best = None, float("inf")
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        t_best = min(t_best, time.perf_counter() - t)
    return t_best, out


def line(what: str, t_np: float, t_sp: float) -> None:
    print(f"{what:<44} numpy {t_np * 1e3:9.1f} ms   scipy {t_sp * 1e3:8.1f} ms   x{t_np / t_sp:5.1f}")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    beam_model.SCIPY_MIN_CELLS = 0
    rng = np.random.default_rng(0)
    sparse = np.zeros((2000, 2000), dtype=bool)
    sparse[[0, -1], :] = sparse[:, [0, -1]] = True
    sparse[1000, 300:1700] = True
    for name, occ in (("distance transform 2000x2000, walls", sparse),
                      ("distance transform 2000x2000, 2 % occupied", rng.random((2000, 2000)) < 0.02)):
        t_np, a = best(lambda occ=occ: distance_transform_numpy(occ), args.repeat)
        t_sp, b = best(lambda occ=occ: distance_transform(occ), args.repeat)
        assert np.array_equal(a, b)
        line(name, t_np, t_sp)
    for n in (50, 200, 500):
        cost = rng.random((n, n))
        t_np, a = best(lambda cost=cost: min_cost_assignment_numpy(cost), args.repeat)
        t_sp, b = best(lambda cost=cost: min_cost_assignment(cost), args.repeat)
        assert a == b
        line(f"assignment {n}x{n}", t_np, t_sp)


if __name__ == "__main__":
    main()
