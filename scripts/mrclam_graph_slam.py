"""Graph SLAM on every robot of a MRCLAM data set (docs/slam.md, "Graph SLAM on MRCLAM"):
per robot the path's ATE with its 95 % block-bootstrap interval (30 s blocks, as the MRCLAM
tables), the pose ANEES (the graph's marginals), the final map's GOSPA against the survey
(c = 1 m), the GOSPA after a rigid fit and the turn that fit needs, the readings dropped, the
heading error at the first reading (where the graph's pose is dead reckoning: it sets the
map's frame) and the path's ATE after a rigid fit onto the truth (its shape, without its
frame). With ``--ekf-slam`` EKF-SLAM runs on the same robot (the run ``beacon-sim mrclam DIR
--robot N --slam`` makes) and a second table gives both ATEs and their difference, graph
minus EKF-SLAM, with a paired interval (the same 30 s blocks drawn for both).

Usage: python scripts/mrclam_graph_slam.py [DIR] [--command-delay S] [--robots 1,2,3,4,5]
[--no-pose-covariances] [--ekf-slam] (without the poses' marginals, most of the CPU: no
ANEES then) (DIR: a data set folder, default where BEACON_SIM_MRCLAM says; the noise
leave-one-robot-out, as ``beacon-sim mrclam DIR --robot N --slam --graph``, whose graph_slam
row this is).
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.metrics import pose_errors
from beacon_sim.evaluation.intervals import LEVEL, REPLICATES, SEED, ratio_of_sums, text
from beacon_sim.evaluation.slam_metrics import gospa
from beacon_sim.evaluation.slam_run import GOSPA_CUTOFF_M, aligned_gospa, rigid_fit
from beacon_sim.io.mrclam import ROBOT_SUBJECTS, MrclamData, find_dataset, load_mrclam
from beacon_sim.runs.mrclam import calibration_for, nees_or_inf, run_mrclam
from beacon_sim.runs.mrclam.graph_slam import graph_slam_track
from beacon_sim.runs.mrclam.runners import run_span

BLOCK_S = 30.0


def block_sums(data: MrclamData, times: np.ndarray, means: np.ndarray, t0: float, n_blocks: int
               ) -> tuple[np.ndarray, np.ndarray, float, float, np.ndarray]:
    """Per 30 s block from ``t0``: the squared position errors' sum and the count (n_blocks,),
    the ATE [m], the ATE after the rigid motion that best fits the whole path onto the truth
    (the ATE of Sturm et al. 2012, which aligns first), and that aligned error's squared sum
    per block (n_blocks,)."""
    truth, ok = data.truth_at(times)
    e = pose_errors(means[ok], truth[ok])
    blk = np.floor((times[ok] - t0) / BLOCK_S).astype(int)
    sq = np.bincount(blk, e[:, 0] ** 2 + e[:, 1] ** 2, minlength=n_blocks)
    cnt = np.bincount(blk, minlength=n_blocks).astype(float)
    rot, shift = rigid_fit(means[ok, :2], truth[ok, :2])
    moved = means[ok, :2] @ rot.T + shift
    sq_aligned = np.bincount(blk, np.sum((moved - truth[ok, :2]) ** 2, axis=1), minlength=n_blocks)
    aligned = math.sqrt(float(sq_aligned.sum() / cnt.sum()))
    return sq, cnt, math.sqrt(sq.sum() / cnt.sum()), aligned, sq_aligned


def paired_difference(sq_a: np.ndarray, cnt_a: np.ndarray, sq_b: np.ndarray, cnt_b: np.ndarray
                      ) -> tuple[float, float]:
    """95 % block-bootstrap interval of ATE_a - ATE_b, the same blocks drawn for both (blocks
    where either track has no estimate left out)."""
    keep = (cnt_a > 0) & (cnt_b > 0)
    sq_a, cnt_a, sq_b, cnt_b = sq_a[keep], cnt_a[keep], sq_b[keep], cnt_b[keep]
    idx = np.random.default_rng(SEED).integers(0, keep.sum(), size=(REPLICATES, int(keep.sum())))
    d = (np.sqrt(sq_a[idx].sum(1) / cnt_a[idx].sum(1)) - np.sqrt(sq_b[idx].sum(1) / cnt_b[idx].sum(1)))
    a = (1.0 - LEVEL) / 2.0
    return (float(np.percentile(d, 100 * a, method="lower")),
            float(np.percentile(d, 100 * (1 - a), method="higher")))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dir", nargs="?")
    ap.add_argument("--command-delay", type=float, default=0.0, metavar="S")
    ap.add_argument("--robots", default=",".join(str(r) for r in ROBOT_SUBJECTS))
    ap.add_argument("--no-pose-covariances", action="store_true")
    ap.add_argument("--ekf-slam", action="store_true")
    args = ap.parse_args()
    folder = find_dataset(args.dir)
    print(f"graph SLAM on {folder.name}, commands delayed {args.command_delay:g} s")
    print("| robot | ATE [m] | pose ANEES | map GOSPA [m] | GOSPA after a rigid fit [m] (map turned by) "
          "| readings dropped | heading error at the first reading [deg] (at s) "
          "| path ATE after a rigid fit [m] | CPU [s] |")
    print("|---|---|---|---|---|---|---|---|---|")
    versus = []
    for robot in (int(r) for r in args.robots.split(",")):
        c0 = time.process_time()
        data = load_mrclam(folder, robot)
        t0, t1 = run_span([data], None)
        tr, _ = graph_slam_track(data, calibration_for(data, "others", t1), t0, t1, args.command_delay,
                                 not args.no_pose_covariances)
        n_blocks = int((t1 - t0) // BLOCK_S) + 1
        sq, cnt, ate, aligned, sq_al = block_sums(data, tr.times, tr.means, t0, n_blocks)
        truth, ok = data.truth_at(tr.times)
        anees = ("-" if args.no_pose_covariances
                 else f"{np.mean(nees_or_inf(pose_errors(tr.means[ok], truth[ok]), tr.covs[ok])):.2f}")
        lm = tr.filter.landmarks()
        ids = np.array(sorted(k for k in data.landmarks if k not in ROBOT_SUBJECTS))
        xy = np.array([data.landmarks[k] for k in ids])
        shape, turn = aligned_gospa(lm.means, xy, lm.ids, ids)
        g = gospa(lm.means, xy, c=GOSPA_CUTOFF_M).value
        k = tr.filter.first_reading
        first = "-"
        if k is not None:
            true_k, ok_k = data.truth_at(tr.times[[k]])
            if ok_k[0]:
                err = math.degrees(float(wrap(tr.means[k, 2] - true_k[0, 2])))
                first = f"{err:+.2f} ({tr.times[k] - t0:.1f})"
        print(f"| {robot} | {ate:.3f} {text(ratio_of_sums(sq[cnt > 0], cnt[cnt > 0], sqrt=True), '.3f')} "
              f"| {anees} | {g:.3f} | {shape:.3f} ({math.degrees(turn):+.1f}°) "
              f"| {tr.filter.rejected} | {first} | {aligned:.3f} | {time.process_time() - c0:.0f} |",
              flush=True)
        if args.ekf_slam:
            ek = run_mrclam(data, ["ekf_slam"], slam=True).tracks["ekf_slam"]
            sq_e, cnt_e, ate_e, aligned_e, sq_al_e = block_sums(data, ek.times, ek.means, t0, n_blocks)
            iv_e = text(ratio_of_sums(sq_e[cnt_e > 0], cnt_e[cnt_e > 0], sqrt=True), ".3f")
            lo, hi = paired_difference(sq, cnt, sq_e, cnt_e)
            alo, ahi = paired_difference(sq_al, cnt, sq_al_e, cnt_e)
            versus.append(f"| {robot} | {ate:.3f} | {ate_e:.3f} {iv_e} "
                          f"| {ate - ate_e:+.3f} [{lo:+.3f}, {hi:+.3f}] | {aligned:.3f} | {aligned_e:.3f} "
                          f"| {aligned - aligned_e:+.3f} [{alo:+.3f}, {ahi:+.3f}] |")
    if versus:
        print("\n| robot | graph SLAM ATE [m] | EKF-SLAM ATE [m] | graph - EKF-SLAM [m] (paired) "
              "| aligned ATE: graph [m] | EKF-SLAM [m] | graph - EKF-SLAM, aligned [m] (paired) |")
        print("|---|---|---|---|---|---|---|")
        print("\n".join(versus))


if __name__ == "__main__":
    main()
