"""One Gauss-Newton step of graph SLAM on the Intel pose graph (1,728 poses, 4,830 edges),
beside gtsam's, in the same run.

Run:  .venv/bin/python benchmarks/bench_graph_step.py [--repeats N]

Both start from the file's own initial values and take the same steps (4 to converge); a
step of this program is: linearise every edge (numpy, by edge class), assemble H and b
(COO triplets), factorise with scipy's sparse LU (SuperLU) and move the nodes. gtsam's is one
iteration of its GaussNewtonOptimizer (linearise, eliminate, retract). Reported: the CPU time
per step (the median of the repeats' per-step means), and the ratio to gtsam's; target 2x.
The graph is found in BEACON_SIM_GRAPHS or ../shared/data/graphs beside the checkout.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

from figures import figure

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from beacon_sim.filters.graph.solver import GraphSolver  # noqa: E402
from beacon_sim.io.g2o import read_g2o  # noqa: E402

STEPS = 4


def graph_path() -> Path:
    where = os.environ.get("BEACON_SIM_GRAPHS")
    return (Path(where) if where else ROOT.parent / "shared" / "data" / "graphs") / "intel.g2o"


def ours(path: Path, repeats: int) -> tuple[float, float]:
    """CPU ms per step (median over repeats) and the final chi2."""
    g = read_g2o(path)
    GraphSolver(g).step()  # imports scipy, warms the caches
    per = []
    chi2 = float("nan")
    for _ in range(repeats):
        s = GraphSolver(g)
        t0 = time.process_time()
        for _ in range(STEPS):
            s.step()
        per.append(1e3 * (time.process_time() - t0) / STEPS)
        chi2 = s.graph.chi2()
    return statistics.median(per), chi2


def theirs(path: Path, repeats: int) -> tuple[float, float] | None:
    try:
        import gtsam
    except ImportError:
        return None
    g = read_g2o(path)
    fg, v = gtsam.NonlinearFactorGraph(), gtsam.Values()
    for k, p in enumerate(g.poses):
        v.insert(k, gtsam.Pose2(*p))
    fg.add(gtsam.PriorFactorPose2(0, gtsam.Pose2(*g.poses[0]), gtsam.noiseModel.Isotropic.Sigma(3, 1e-6)))
    for es in g.edges:
        for i, j, z, info in zip(es.i.tolist(), es.j.tolist(), es.z, es.info, strict=True):
            noise = gtsam.noiseModel.Gaussian.Information(info)
            fg.add(gtsam.BetweenFactorPose2(i, j, gtsam.Pose2(*z), noise))
    per = []
    chi2 = float("nan")
    for _ in range(repeats):
        opt = gtsam.GaussNewtonOptimizer(fg, v, gtsam.GaussNewtonParams())
        t0 = time.process_time()
        for _ in range(STEPS):
            opt.iterate()
        per.append(1e3 * (time.process_time() - t0) / STEPS)
        chi2 = 2.0 * fg.error(opt.values())
    return statistics.median(per), chi2


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    path = graph_path()
    if not path.is_file():
        print(f"intel.g2o not found at {path} (set BEACON_SIM_GRAPHS)")
        return
    ms, chi2 = ours(path, args.repeats)
    peer = theirs(path, args.repeats)
    print(f"load average {os.getloadavg()[0]:.1f}; {STEPS} Gauss-Newton steps from the file's values, "
          f"{args.repeats} repeats")
    print(f"beacon-sim  {ms:7.1f} ms CPU a step   final chi2 {chi2:.2f}")
    if peer is None:
        print("gtsam       not installed (pip install gtsam): no peer")
        figure("graph SLAM: one Gauss-Newton step, intel.g2o", ms, "ms", cpu=ms)
        return
    pms, pchi2 = peer
    print(f"gtsam       {pms:7.1f} ms CPU a step   final chi2 {pchi2:.2f}   ratio {ms / pms:.2f}")
    figure("graph SLAM: one Gauss-Newton step, intel.g2o", ms, "ms", peer="gtsam 4.3 GN iteration",
           peer_value=pms, target=2.0, target_of="ratio", cpu=ms)


if __name__ == "__main__":
    main()
