"""Graph SLAM on every robot of a MRCLAM data set (docs/slam.md, "Graph SLAM on MRCLAM"):
per robot the path's ATE with its 95 % block-bootstrap interval (30 s blocks, as the MRCLAM
tables), the pose ANEES (the graph's marginals), the final map's GOSPA against the survey
(c = 1 m), the GOSPA after a rigid fit and the turn that fit needs, and the readings dropped.

Usage: python scripts/mrclam_graph_slam.py [DIR] [--command-delay S] [--robots 1,2,3,4,5]
[--no-pose-covariances] (without the poses' marginals, most of the CPU: no ANEES then)
(DIR: a data set folder, default where BEACON_SIM_MRCLAM says; the noise leave-one-robot-out,
as ``beacon-sim mrclam DIR --robot N --slam --graph``, whose graph_slam row this is).
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from beacon_sim.core.metrics import pose_errors
from beacon_sim.evaluation.intervals import ratio_of_sums, text
from beacon_sim.evaluation.slam_metrics import gospa
from beacon_sim.evaluation.slam_run import GOSPA_CUTOFF_M, aligned_gospa
from beacon_sim.io.mrclam import ROBOT_SUBJECTS, find_dataset, load_mrclam
from beacon_sim.runs.mrclam import calibration_for, nees_or_inf
from beacon_sim.runs.mrclam.graph_slam import graph_slam_track
from beacon_sim.runs.mrclam.runners import run_span

BLOCK_S = 30.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dir", nargs="?")
    ap.add_argument("--command-delay", type=float, default=0.0, metavar="S")
    ap.add_argument("--robots", default=",".join(str(r) for r in ROBOT_SUBJECTS))
    ap.add_argument("--no-pose-covariances", action="store_true")
    args = ap.parse_args()
    folder = find_dataset(args.dir)
    print(f"graph SLAM on {folder.name}, commands delayed {args.command_delay:g} s")
    print("| robot | ATE [m] | pose ANEES | map GOSPA [m] | GOSPA after a rigid fit [m] (map turned by) "
          "| readings dropped | CPU [s] |")
    print("|---|---|---|---|---|---|---|")
    for robot in (int(r) for r in args.robots.split(",")):
        c0 = time.process_time()
        data = load_mrclam(folder, robot)
        t0, t1 = run_span([data], None)
        tr, _ = graph_slam_track(data, calibration_for(data, "others", t1), t0, t1, args.command_delay,
                                 not args.no_pose_covariances)
        truth, ok = data.truth_at(tr.times)
        e = pose_errors(tr.means[ok], truth[ok])
        t = tr.times[ok]
        blk = np.floor((t - t[0]) / BLOCK_S).astype(int)
        cnt = np.bincount(blk).astype(float)
        keep = cnt > 0
        sq = np.bincount(blk, e[:, 0] ** 2 + e[:, 1] ** 2)[keep]
        ate = math.sqrt(sq.sum() / cnt[keep].sum())
        anees = ("-" if args.no_pose_covariances else f"{np.mean(nees_or_inf(e, tr.covs[ok])):.2f}")
        lm = tr.filter.landmarks()
        ids = np.array(sorted(k for k in data.landmarks if k not in ROBOT_SUBJECTS))
        xy = np.array([data.landmarks[k] for k in ids])
        shape, turn = aligned_gospa(lm.means, xy, lm.ids, ids)
        g = gospa(lm.means, xy, c=GOSPA_CUTOFF_M).value
        print(f"| {robot} | {ate:.3f} {text(ratio_of_sums(sq, cnt[keep], sqrt=True), '.3f')} | {anees} "
              f"| {g:.3f} | {shape:.3f} ({math.degrees(turn):+.1f}°) "
              f"| {tr.filter.rejected} | {time.process_time() - c0:.0f} |", flush=True)


if __name__ == "__main__":
    main()
