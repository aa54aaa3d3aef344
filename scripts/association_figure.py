"""Draw docs/figures/association_lookalike.png: docs/association.md's hand-built case.

Two beacons 0.2 rad apart, a heading uncertain by 0.2 rad, both readings 0.15 rad to the left
(the robot turned less than the estimate says). Left: nearest neighbour's crossed pairing;
right: JCBB's. The numbers come from beacon_sim.filters.association, not from this script.
Usage: python scripts/association_figure.py [--out PNG]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from beacon_sim.filters import association as assoc

OUT = Path(__file__).resolve().parent.parent / "docs" / "figures" / "association_lookalike.png"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(OUT))
    args = ap.parse_args()
    xy = np.array([[5 * math.cos(0.1), 5 * math.sin(0.1)], [5 * math.cos(-0.1), 5 * math.sin(-0.1)]])
    ids = np.array([7, 8])
    P = np.diag([1e-4, 1e-4, 0.2 ** 2])
    z = np.array([[0.25], [0.05]])
    lin = assoc.linearise("bearing", z, np.zeros(3), P, xy, [0.01])
    results = [("nearest neighbour", assoc.nearest_neighbour(lin, ids)), ("JCBB", assoc.jcbb(lin, ids))]
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.6), sharey=True)
    for ax, (name, res) in zip(axes, results, strict=True):
        ax.plot(0, 0, "o", color="0.2")
        ax.annotate("estimate, heading 0\n(grey: +-2 sigma)", (0, 0), (0.2, -0.75), fontsize=8)
        wedge = np.linspace(-0.4, 0.4, 30)
        ax.fill(np.r_[0, 6 * np.cos(wedge), 0], np.r_[0, 6 * np.sin(wedge), 0], color="0.92", zorder=0)
        ax.plot([0, 6 * math.cos(-0.15)], [0, 6 * math.sin(-0.15)], ":", color="0.5", lw=1)
        ax.annotate("true heading (-0.15 rad)", (6 * math.cos(-0.15), 6 * math.sin(-0.15)), fontsize=8,
                    color="0.4")
        for k, (bx, by) in enumerate(xy):
            ax.plot(bx, by, "s", color="tab:blue", ms=9)
            ax.annotate(f"beacon {ids[k]}", (bx, by), (bx + 0.2, by + (0.1 if k == 0 else -0.3)),
                        fontsize=9)
        for i, b in enumerate(z[:, 0]):
            ax.plot([0, 6 * math.cos(b)], [0, 6 * math.sin(b)], color="tab:orange", lw=1.5)
            ax.annotate(f"reading {i + 1} ({b:.2f} rad)", (6 * math.cos(b), 6 * math.sin(b)), fontsize=8,
                        color="tab:orange")
        right = res.beacon_ids == (7, 8)
        for i, bid in enumerate(res.beacon_ids):
            if bid is None:
                continue
            b = z[i, 0]
            j = int(np.flatnonzero(ids == bid)[0])
            arrow = {"arrowstyle": "->", "color": "tab:green" if right else "tab:red", "lw": 2,
                     "connectionstyle": "arc3,rad=0.2"}
            ax.annotate("", xy[j], (6 * math.cos(b), 6 * math.sin(b)), arrowprops=arrow)
        limit = assoc.gate(0.99, res.dof)
        verdict = "jointly compatible" if res.joint_nis <= limit else "jointly incompatible"
        pairs = ", ".join(f"reading {i + 1} -> beacon {b}" for i, b in enumerate(res.beacon_ids))
        ax.set_title(f"{name}: {pairs}\njoint NIS {res.joint_nis:.3g} (99 % gate {limit:.2f}): {verdict}",
                     fontsize=10)
        ax.set_xlim(-0.3, 8.6)
        ax.set_ylim(-1.3, 2.0)
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
    axes[0].set_ylabel("y [m]")
    fig.tight_layout()
    fig.savefig(args.out, dpi=110, bbox_inches="tight")
    print(args.out)


if __name__ == "__main__":
    main()
