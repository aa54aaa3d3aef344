"""When a SLAM filter's map turns on a MRCLAM robot (docs/slam.md, "Where the frame is lost"):
the filter's map after 2, 5, 10, 20, 30, 60, 120, 300 and 600 s and at the end, each as its
landmark count, the rotation of the rigid fit onto the survey (the map's turn) and the
filter's heading error then.

Usage: python scripts/mrclam_map_turn.py [DIR] [--filter ekf_slam] [--robots 1,2,3,4,5]
(noise leave-one-robot-out, as ``beacon-sim mrclam DIR --robot N --slam``).
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.evaluation.slam_run import aligned_gospa
from beacon_sim.io.mrclam import ROBOT_SUBJECTS, find_dataset, load_mrclam
from beacon_sim.runs.mrclam import run_mrclam

TIMES_S = (2, 5, 10, 20, 30, 60, 120, 300, 600)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dir", nargs="?")
    ap.add_argument("--filter", default="ekf_slam")
    ap.add_argument("--robots", default=",".join(str(r) for r in ROBOT_SUBJECTS))
    args = ap.parse_args()
    folder = find_dataset(args.dir)
    for robot in (int(r) for r in args.robots.split(",")):
        data = load_mrclam(folder, robot)
        run = run_mrclam(data, [args.filter], slam=True, record_maps=True)
        tr, hist = run.tracks[args.filter], run.map_history[args.filter]
        beacons = list(run.scenario.world.beacons)
        ids = np.array([b.id for b in beacons])
        xy = np.array([(b.x, b.y) for b in beacons])
        truth, _ = data.truth_at(tr.times)
        heading_err = np.degrees(wrap(tr.means[:, 2] - truth[:, 2]))
        cells = []
        for t in [run.t_start + s for s in TIMES_S if run.t_start + s < hist.times[-1]] + [hist.times[-1]]:
            m = hist.at(t)
            if m is None:
                continue
            _, turn = aligned_gospa(np.asarray(m.means).reshape(-1, 2), xy, m.ids, ids)
            k = int(np.searchsorted(tr.times, t, side="right")) - 1
            cells.append(f"{t - run.t_start:.0f} s: {len(m.means)} landmarks, turned "
                         f"{math.degrees(turn):+.1f}°, heading error {heading_err[k]:+.1f}°")
        print(f"robot {robot} {args.filter}: " + " | ".join(cells), flush=True)


if __name__ == "__main__":
    main()
