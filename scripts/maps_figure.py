"""The figure of docs/maps.md: a map drawn from walls, one scan, the likelihood field.

    python scripts/maps_figure.py [--seed 0] [--out docs/figures]
    SDL_VIDEODRIVER=dummy python scripts/maps_figure.py --window   # maps_field.png

Left: a corridor with doors (after seed 004) and a room, the robot, its 90 beams (hits
blue, max-range readings grey) with beam-model noise drawn from a seeded generator. Right:
the likelihood field's per-beam probability over the map, 2000 particles (uniform over the
free cells, as mcl's global start; 20 of them drawn around the true pose) and the 20 the
field scores highest for that scan.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from beacon_sim.core.beam_model import LikelihoodField, RangeModelParams, sample_beam
from beacon_sim.core.occupancy import from_walls
from beacon_sim.core.raycast import scan

MAX_RANGE = 6.0


def corridor_map():
    """12 m x 6 m: a corridor along y in [0, 1.2] with three doors into a room above it."""
    outline = [(0, 0), (12, 0), (12, 6), (0, 6), (0, 0)]
    wall_with_doors = [[(0, 1.2), (2.0, 1.2)], [(3.0, 1.2), (6.0, 1.2)], [(7.0, 1.2), (10.0, 1.2)],
                       [(11.0, 1.2), (12.0, 1.2)]]
    pillars = [[(4.0, 3.0), (4.6, 3.0), (4.6, 3.6), (4.0, 3.6)],
               [(8.0, 4.0), (9.0, 4.0), (9.0, 4.4), (8.0, 4.4)]]
    return from_walls((0, 0, 12, 6), 0.05, segments=[outline, *wall_with_doors], polygons=pillars)


def window_field_figure(out: Path, frames: int = 150) -> Path:
    """docs/figures/maps_field.png: the window on the symmetric room (autopilot, 1100 x 640,
    the scenario's filters and seed), L pressed at the start, the frame after ``frames``
    frames (2.5 s). Needs pygame (SDL_VIDEODRIVER=dummy for no screen)."""
    import pygame

    from beacon_sim.app.main import App
    from beacon_sim.core.scenario import load_scenario
    from beacon_sim.runs.live import Session

    sc = load_scenario("symmetric_room")
    session = Session(sc, list(sc.default_filters), sc.seed)
    session.toggle_autopilot()
    app = App(session, (1100, 640), scripted=True)
    try:
        for t in (pygame.KEYDOWN, pygame.KEYUP):
            pygame.event.post(pygame.event.Event(t, key=pygame.K_l, mod=0, unicode="", scancode=0))
        app.run(frames)
        path = out / "maps_field.png"
        app.save_screenshot(path)
    finally:
        app.close()
    return path


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default="docs/figures")
    ap.add_argument("--window", action="store_true",
                    help="instead: the window's likelihood-field figure (maps_field.png)")
    args = ap.parse_args()
    if args.window:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        print(window_field_figure(out))
        return
    grid = corridor_map()
    params = RangeModelParams(laser_max_range=MAX_RANGE, sigma_hit=0.05, z_hit=0.9, z_rand=0.05,
                              z_short=0.03, z_max=0.02, laser_likelihood_max_dist=1.0)
    rng = np.random.default_rng(args.seed)
    pose = np.array([6.5, 3.0, 0.4])
    rel, expected = scan(grid, pose, 90, 2 * np.pi, MAX_RANGE)
    z = sample_beam(expected, params, rng)
    field = LikelihoodField(grid, params)

    (x0, y0, _), (w, h) = grid.origin, grid.size_m
    extent = (x0, x0 + w, y0, y0 + h)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(13, 3.9), constrained_layout=True)
    ax1.imshow(grid.occupied, origin="lower", extent=extent, cmap="Greys", vmin=0, vmax=1.6)
    ends = pose[:2] + z[:, None] * np.column_stack([np.cos(pose[2] + rel), np.sin(pose[2] + rel)])
    for (x, y), r in zip(ends, z, strict=True):
        # Most readings end on the wall the ray meets; the model's short, random and max
        # parts give a few that end before it, beyond it, or at max range (grey).
        hit = r < MAX_RANGE
        ax1.plot([pose[0], x], [pose[1], y], color="tab:blue" if hit else "0.7", lw=0.6)
    hit = z < MAX_RANGE
    ax1.plot(ends[hit, 0], ends[hit, 1], ".", color="tab:red", ms=3, label="beam end points")
    ax1.plot(*pose[:2], "o", color="tab:orange", ms=7, label="robot")
    ax1.set_title("walls (from_walls), a 90-beam scan with beam-model noise")
    ax1.legend(loc="lower right", fontsize=8)
    ax1.set_xlabel("x [m]")
    ax1.set_ylabel("y [m]")

    prob = field.beam_probability(field.distance)
    ax2.imshow(prob, origin="lower", extent=extent, cmap="viridis")
    # As mcl's global start: uniform over the map's free cells only (none in a wall or pillar).
    free = np.flatnonzero(grid.cells.ravel() == 0)
    cells = free[rng.integers(0, free.size, 2000)]
    cols = grid.shape[1]
    uv = np.column_stack([cells % cols + rng.random(2000), cells // cols + rng.random(2000)])
    particles = np.column_stack([grid.grid_to_world(uv), rng.uniform(-np.pi, np.pi, 2000)])
    particles[:20] = pose + rng.normal(0, [0.1, 0.1, 0.05], (20, 3))
    logw = field.log_likelihood(particles, z, rel)
    best = np.argsort(logw)[-20:]
    ax2.scatter(particles[:, 0], particles[:, 1], color="white", s=1, alpha=0.5,
                label="2000 particles (20 near the robot)")
    ax2.scatter(particles[best, 0], particles[best, 1], color="tab:red", s=10,
                label="the 20 most likely for this scan")
    ax2.legend(loc="upper left", fontsize=8, framealpha=0.9)
    ax2.plot(*pose[:2], "o", mfc="none", mec="white", ms=9)
    ax2.set_title("likelihood field z_hit N(d; 0, sigma) + z_rand / z_max; particles by log p(scan)")
    ax2.set_xlabel("x [m]")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    fig.savefig(out / "maps_scan_field.png", dpi=110)
    print(out / "maps_scan_field.png")


if __name__ == "__main__":
    main()
