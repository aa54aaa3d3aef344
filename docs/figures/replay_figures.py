"""Regenerate the figures of docs/replay.md (needs matplotlib and MRCLAM Dataset 6).

    python docs/figures/replay_figures.py [DIR]

DIR: the data set's folder (default: where BEACON_SIM_MRCLAM says; docs/mrclam.md).
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from beacon_sim.io.mrclam import load_mrclam
from beacon_sim.runs.mrclam import run_mrclam

OUT = Path(__file__).parent


def main(folder: str | None) -> None:
    data = load_mrclam(folder, 1)
    run = run_mrclam(data, ["ekf", "ukf", "dead_reckoning"])
    fig, ax = plt.subplots(figsize=(7, 7))
    gt = data.groundtruth
    ax.plot(gt[:, 1], gt[:, 2], color="k", lw=1.2, label="ground truth (Vicon)")
    colors = {"ekf": "tab:blue", "ukf": "tab:orange", "dead_reckoning": "tab:gray"}
    for name, tr in run.tracks.items():
        m = np.array(tr.means)
        ax.plot(m[:, 0], m[:, 1], lw=0.8, color=colors[name], label=name,
                ls="--" if name == "ukf" else "-")
    lm = np.array([[b.x, b.y] for b in run.scenario.world.beacons])
    ax.scatter(lm[:, 0], lm[:, 1], marker="s", color="tab:green", label="landmarks", zorder=3)
    ax.set_aspect("equal")
    ax.set_xlim(-2.5, 6.5)
    ax.set_ylim(-6.5, 6.5)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("MRCLAM Dataset 6, robot 1, 888 s")
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(OUT / "mrclam_robot1_trajectory.png", dpi=90)

    fig, ax = plt.subplots(figsize=(8, 3.2))
    for name, tr in run.tracks.items():
        t = np.array(tr.times)
        truth, ok = data.truth_at(t)
        e = np.hypot(*(np.array(tr.means)[:, :2] - truth[:, :2]).T)
        e[~ok] = np.nan
        ax.plot(t - data.t0, e, lw=0.8, color=colors[name], label=name)
    ax.set_yscale("log")
    ax.set_xlabel("time since the first odometry row [s]")
    ax.set_ylabel("position error [m]")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(OUT / "mrclam_robot1_error.png", dpi=90)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None)
