"""Draw the window icon, assets/icon.png: the window's robot inside a covariance ellipse.

Usage: python scripts/make_icon.py [--size 64] [--out assets/icon.png]

Drawn at 4x with pygame and scaled down smoothly, so the edges come out anti-aliased.
The robot outline is ``beacon_sim.app.shapes.chassis`` and the colours are the window's
palette, so the icon looks like what the window shows.
"""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path

import pygame

from beacon_sim.app import palette, shapes

OUT = Path(__file__).resolve().parent.parent / "assets" / "icon.png"
OVERSAMPLE = 4


def draw_icon(size: int = 64) -> pygame.Surface:
    """The icon, ``size`` x ``size`` pixels with alpha."""
    n = size * OVERSAMPLE
    big = pygame.Surface((n, n), pygame.SRCALPHA)
    u = n / 64.0  # one pixel of the 64 px design

    # Tile: a light rounded square with a dark edge, readable on light and dark task bars.
    tile = pygame.Rect(0, 0, n, n).inflate(-2 * u, -2 * u)
    pygame.draw.rect(big, palette.BACKGROUND, tile, border_radius=round(12 * u))
    pygame.draw.rect(big, palette.PANEL_EDGE, tile, width=round(2.5 * u), border_radius=round(12 * u))

    # Covariance ellipse: a filter's blue, long axis tilted 30 degrees, translucent fill.
    blue = palette.OKABE_ITO[0]
    ell = pygame.Surface((round(52 * u), round(30 * u)), pygame.SRCALPHA)
    pygame.draw.ellipse(ell, (*blue, 70), ell.get_rect())
    pygame.draw.ellipse(ell, (*blue, 255), ell.get_rect(), width=round(3.5 * u))
    ell = pygame.transform.rotate(ell, 30.0)
    centre = (n / 2, n / 2 + 2 * u)
    big.blit(ell, ell.get_rect(center=(round(centre[0]), round(centre[1]))))

    # The robot (the window's chassis outline), heading up and to the right (screen y is down).
    pose = (centre[0], centre[1], -math.radians(30.0))
    body, wheels = shapes.chassis(pose, 11 * u)
    for w in wheels:
        pygame.draw.polygon(big, palette.ROBOT_WHEEL, [tuple(p) for p in w])
    pygame.draw.polygon(big, palette.ROBOT, [tuple(p) for p in body])
    mark = shapes.heading_mark(pose, 11 * u)
    pygame.draw.line(big, palette.ROBOT_MARK, tuple(mark[0]), tuple(mark[1]), round(3 * u))

    # A seen beacon in the top-left corner.
    pygame.draw.circle(big, palette.BEACON_SEEN, (round(14 * u), round(14 * u)), round(5 * u))
    pygame.draw.circle(big, palette.BEACON_SEEN_RING, (round(14 * u), round(14 * u)), round(5 * u),
                       width=round(1.5 * u))
    return pygame.transform.smoothscale(big, (size, size))


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=64, help="icon side in pixels (64)")
    ap.add_argument("--out", type=Path, default=OUT, help=f"output PNG ({OUT})")
    args = ap.parse_args(argv)
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")  # no window is opened
    pygame.display.init()
    try:
        pygame.image.save(draw_icon(args.size), str(args.out))
    finally:
        pygame.display.quit()
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
