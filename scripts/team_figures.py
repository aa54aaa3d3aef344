"""Figures of docs/multi-robot.md: team_sparse, one seeded run.

    python scripts/team_figures.py [--seed 1] [--out docs/figures]

Left: the true paths and each filter's estimate of the explorer (the robot that sees no
beacon); right: each robot's position error over time, independent against centralised and CI.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from beacon_sim.core.scenario import load_team_scenario
from beacon_sim.runs.headless import run_headless


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", default="docs/figures")
    args = ap.parse_args()
    team = load_team_scenario("team_sparse")
    r = run_headless(team, ["independent", "centralised", "ci"], seed=args.seed)
    truth = r.true_poses
    t = np.array([s.time for s in r.team_steps])
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(13, 4.8))
    b = np.array([[be.x, be.y] for be in team.world.beacons])
    ax.plot(b[:, 0], b[:, 1], "k^", label="beacons")
    colours = {"independent": "tab:red", "centralised": "tab:blue", "ci": "tab:green"}
    for i, robot in enumerate(team.robots):
        ax.plot(truth[:, i, 0], truth[:, i, 1], "k-", lw=1, alpha=0.5,
                label="true paths" if i == 0 else None)
        ax.annotate(robot.name, truth[0, i, :2])
    e = [rr.name for rr in team.robots].index("explorer")
    for name, c in colours.items():
        m = np.array(r.tracks[name].means)
        ax.plot(m[:, e, 0], m[:, e, 1], "-", color=c, lw=1, label=f"explorer: {name}")
    xmin, ymin, xmax, ymax = team.world.bounds
    ax.set_xlim(xmin, xmax)
    ax.set_ylim(ymin, ymax)
    ax.set_aspect("equal")
    ax.set_title(f"team_sparse, seed {args.seed}: paths")
    ax.legend(fontsize=7, loc="upper left")
    styles = ["-", "--", ":"]
    for name, c in colours.items():
        m = np.array(r.tracks[name].means)
        for i, robot in enumerate(team.robots):
            err = np.hypot(*(m[:, i, :2] - truth[:, i, :2]).T)
            bx.plot(t, err, styles[i], color=c, lw=1, label=f"{robot.name}: {name}")
    bx.set_xlabel("time [s]")
    bx.set_ylabel("position error [m]")
    bx.set_title("position error per robot")
    bx.legend(fontsize=7, ncol=3)
    fig.tight_layout()
    out = Path(args.out) / "team_sparse.png"
    fig.savefig(out, dpi=110)
    print(out)


if __name__ == "__main__":
    main()
