"""The window figure of docs/slam.md's real-data section: Dataset 6 robot 1 with ``--slam``
(EKF-SLAM and FastSLAM 2.0 not given the map, the known-map EKF) and graph SLAM on the same
steps (``--graph``), seen at the end of the run: each SLAM filter's final landmarks with their
95 % ellipses (the graph's: its marginal covariances) beside the surveyed ones.

Usage: python docs/figures/mrclam_slam_figure.py DATASET_DIR [ROBOT] [OUT.png]
(DATASET_DIR "": where BEACON_SIM_MRCLAM says; docs/mrclam.md)
(headless: SDL's dummy video driver; the noise from the four other robots, as in results.md).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

from beacon_sim.app.replay import ReplayApp
from beacon_sim.io.mrclam import load_mrclam
from beacon_sim.runs.mrclam import MrclamPlayback, run_mrclam


def main() -> int:
    folder = sys.argv[1] if len(sys.argv) > 1 else None
    robot = int(sys.argv[2]) if len(sys.argv) > 2 else 1
    default = Path(__file__).with_name(f"mrclam_slam_robot{robot}.png")
    out = Path(sys.argv[3]) if len(sys.argv) > 3 else default
    run = run_mrclam(load_mrclam(folder, robot), None, slam=True, record_maps=True, graph=True)
    playback = MrclamPlayback(run)
    app = ReplayApp(playback, scripted=True)
    try:
        app.seek(playback.total_ticks)
        app.run(3)
        app.save_screenshot(str(out))
    finally:
        app.close()
    print(f"wrote {out} (t = {playback.time:.1f} s)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
