"""Write the office floor as a ROS map_server map: assets/maps/office.{yaml,pgm}.

    python scripts/make_office_map.py [--out assets/maps]

A 20 m x 12 m floor at 0.05 m per cell (400 x 240): a corridor along y in [5, 7], four rooms
to the south and three to the north, each with a 1 m door on the corridor, and desks and
cabinets (solid) that make every room look different. The shipped scenario
(scenarios/office.toml) loads the files this writes; the walls are here so that the map can
be rebuilt and changed.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from beacon_sim.core.occupancy import from_walls, save_map

BOUNDS = (0.0, 0.0, 20.0, 12.0)
RESOLUTION = 0.05


def box(x0: float, y0: float, x1: float, y1: float) -> list[tuple[float, float]]:
    return [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]


def office_walls() -> tuple[list, list]:
    """(segments, polygons) of the office [m]."""
    segments = [
        [(0, 0), (20, 0), (20, 12), (0, 12), (0, 0)],                  # the outer walls
        # corridor's south wall, doors at x 2-3, 7-8, 12.5-13.5, 17-18
        [(0, 5), (2, 5)], [(3, 5), (7, 5)], [(8, 5), (12.5, 5)], [(13.5, 5), (17, 5)], [(18, 5), (20, 5)],
        # corridor's north wall, doors at x 3-4, 10-11, 16-17
        [(0, 7), (3, 7)], [(4, 7), (10, 7)], [(11, 7), (16, 7)], [(17, 7), (20, 7)],
        [(5, 0), (5, 5)], [(10, 0), (10, 5)], [(15, 0), (15, 5)],     # south rooms
        [(7, 7), (7, 12)], [(14, 7), (14, 12)],                         # north rooms
    ]
    polygons = [
        box(0.5, 0.5, 2.0, 1.3), box(3.6, 2.0, 4.6, 4.0),               # room S1: desk, cabinet
        box(6.0, 1.0, 9.0, 2.0),                                       # room S2: a long table
        box(10.4, 0.4, 11.0, 1.6), box(13.0, 3.0, 14.5, 4.5),           # room S3
        box(16.0, 0.5, 17.0, 1.5), box(18.0, 0.5, 19.0, 1.5), box(16.0, 3.0, 17.0, 4.0),  # room S4
        box(1.0, 10.0, 5.0, 11.2),                                     # room N1: shelves
        box(8.5, 9.0, 12.0, 10.0),                                     # room N2: a table
        box(15.0, 8.0, 15.8, 8.8), box(18.5, 10.5, 19.5, 11.5),         # room N3
    ]
    return segments, polygons


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[1] / "assets" / "maps")
    args = ap.parse_args()
    segments, polygons = office_walls()
    grid = from_walls(BOUNDS, RESOLUTION, segments=segments, polygons=polygons)
    args.out.mkdir(parents=True, exist_ok=True)
    save_map(grid, args.out / "office.yaml")
    print(f"wrote {args.out / 'office.yaml'} ({grid.shape[1]} x {grid.shape[0]} cells)")


if __name__ == "__main__":
    main()
