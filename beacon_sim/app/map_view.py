"""Drawing a world's walls and a laser scan: the occupancy grid as dark cells under
everything, and each beam of a range_finder reading from the robot to its end point, beams
that hit something in blue with a dot at the hit, no-return (max-range) beams in light grey
up to the wall they meet, readings beyond the wall (random ones) dashed vermillion to it.
On a key (L) the likelihood field goes under the walls: each free cell's distance to the
nearest wall (the transform the likelihood-field model precomputes) as a heat layer, hot at
the walls and fading out at the cap (AMCL's ``laser_likelihood_max_dist``, 2 m).

Geometry stays in metres until the last step (``view.to_px``), as everywhere in app/.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
import pygame

from beacon_sim.app.ahead import scan_walls
from beacon_sim.core.beam_model import distance_transform
from beacon_sim.core.occupancy import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from beacon_sim.core.types import Measurement

#: Occupied cells: near-black, so that walls read as solid on a projector.
WALL = (55, 55, 60)
#: Unknown cells (map_server's grey): between the floor and the walls.
UNKNOWN_CELL = (170, 170, 165)
#: A beam that hit something (Okabe-Ito blue) and one with no return (max range).
BEAM_HIT = (0, 114, 178)
BEAM_NONE = (200, 200, 196)
#: A reading beyond the wall on its beam (a random reading the map cannot explain): vermillion.
BEAM_BEYOND = (213, 94, 0)
#: Largest scaled map image [px] (beyond it the visible part only is scaled).
MAX_MAP_PIXELS = 6_000_000
#: The likelihood field's heat colour (Okabe-Ito vermillion) and its opacity at a wall.
FIELD = (213, 94, 0)
FIELD_ALPHA = 200
#: Distance [m] at which the drawn field has faded out (AMCL's default
#: ``laser_likelihood_max_dist``, the MCL filter's too).
FIELD_CAP = 2.0


def grid_image(grid: OccupancyGrid) -> pygame.Surface:
    """The grid as a (cols x rows) surface with alpha: walls and unknown cells opaque, free
    cells transparent; screen rows run downwards, so the top line is the grid's last row."""
    rows, cols = grid.shape
    img = pygame.Surface((cols, rows), pygame.SRCALPHA)
    rgb = np.zeros((cols, rows, 3), dtype=np.uint8)
    alpha = np.zeros((cols, rows), dtype=np.uint8)
    cells = grid.cells.T[:, ::-1]             # (cols, rows), y down
    for value, colour in ((OCCUPIED, WALL), (UNKNOWN, UNKNOWN_CELL)):
        mask = cells == value
        rgb[mask] = colour
        alpha[mask] = 255
    pygame.surfarray.blit_array(img, rgb)
    a = pygame.surfarray.pixels_alpha(img)
    a[:] = alpha
    del a
    return img


def field_alpha(distance: np.ndarray, cap: float = FIELD_CAP) -> np.ndarray:
    """Opacity 0-255 of the field at cell distances ``distance`` [m] from the nearest wall:
    FIELD_ALPHA at a wall, falling exponentially (length cap / 4) and nothing from ``cap`` on,
    so that a 1 m corridor still shows its middle."""
    d = np.minimum(np.asarray(distance, dtype=float), cap)
    a = FIELD_ALPHA * np.exp(-d / (cap / 4)) * (d < cap)
    return np.round(a).astype(np.uint8)


@lru_cache(maxsize=4)
def field_image(grid: OccupancyGrid, cap: float = FIELD_CAP) -> pygame.Surface:
    """The likelihood field of ``grid`` as a (cols x rows) surface: FIELD with the opacity
    of :func:`field_alpha` on free cells, transparent on walls and unknown cells (the walls
    are drawn over it). Cached per map (grids hash by content)."""
    rows, cols = grid.shape
    d = distance_transform(grid.occupied, cap / grid.resolution) * grid.resolution
    alpha = field_alpha(d, cap)
    alpha[grid.cells != FREE] = 0                 # only free space carries the field
    img = pygame.Surface((cols, rows), pygame.SRCALPHA)
    img.fill((*FIELD, 0))
    a = pygame.surfarray.pixels_alpha(img)
    a[:] = alpha.T[:, ::-1]                    # (cols, rows), y down
    del a
    return img


def draw_field(surf: pygame.Surface, view, grid: OccupancyGrid | None) -> None:
    """The likelihood field of ``grid`` (None: nothing) scaled into ``view``; drawn before
    :func:`draw_map` so that the walls lie on top."""
    if grid is not None:
        blit_grid_image(surf, view, grid, field_image(grid))


def draw_map(surf: pygame.Surface, view, grid: OccupancyGrid | None) -> None:
    """The walls of ``grid`` (None: nothing) scaled into ``view`` on ``surf`` (window
    coordinates)."""
    if grid is not None:
        blit_grid_image(surf, view, grid, grid_image(grid))


def blit_grid_image(surf: pygame.Surface, view, grid: OccupancyGrid, img: pygame.Surface) -> None:
    """A (cols x rows) image of ``grid``'s cells scaled into ``view`` on ``surf``. A rotated
    grid (origin yaw) is rotated as a whole; an axis-aligned one too large to scale whole is
    cropped to the visible cells first."""
    rows, cols = grid.shape
    res, (ox, oy, yaw) = grid.resolution, grid.origin
    scale = view.scale * res                                   # px per cell
    if yaw == 0.0:
        x0, y0, x1, y1 = view.visible_world()
        c0 = max(0, math.floor((x0 - ox) / res))
        c1 = min(cols, math.ceil((x1 - ox) / res))
        r0 = max(0, math.floor((y0 - oy) / res))
        r1 = min(rows, math.ceil((y1 - oy) / res))
        if c1 <= c0 or r1 <= r0:
            return
        sub = img.subsurface(pygame.Rect(c0, rows - r1, c1 - c0, r1 - r0))
        w, h = max(1, round((c1 - c0) * scale)), max(1, round((r1 - r0) * scale))
        if w * h > MAX_MAP_PIXELS:
            return
        corner = view.to_px(np.array([ox + c0 * res, oy + r1 * res]))
        surf.blit(pygame.transform.scale(sub, (w, h)), (round(corner[0]), round(corner[1])))
        return
    w, h = max(1, round(cols * scale)), max(1, round(rows * scale))
    if w * h > MAX_MAP_PIXELS:
        return
    turned = pygame.transform.rotate(pygame.transform.scale(img, (w, h)), math.degrees(yaw))
    centre = view.to_px(grid.grid_to_world(np.array([cols / 2, rows / 2])))
    surf.blit(turned, turned.get_rect(center=(round(centre[0]), round(centre[1]))))


def scan_segments(pose, m: Measurement) -> np.ndarray:
    """Beam segments (n, 2, 2) [m] from the robot along each beam to its reading."""
    p = np.asarray(pose[:2], dtype=float)
    z = np.asarray(m.z, dtype=float)
    a = pose[2] + z[:, 1]
    end = p + z[:, :1] * np.stack([np.cos(a), np.sin(a)], axis=1)
    return np.stack([np.broadcast_to(p, end.shape), end], axis=1)


def draw_scan(surf: pygame.Surface, view, pose, m: Measurement, max_range: float, width: int = 1,
              grid: OccupancyGrid | None = None) -> None:
    """One scan taken at ``pose``: hits blue with a dot; no-return beams light grey; with the
    map ``grid``, a no-return beam stops at the wall it meets (the laser saw nothing up to
    there, not through it), and a reading that lands beyond the wall on its beam (the beam
    model's random readings) is drawn to the wall only, dashed vermillion and ending in a
    ring: a reading the map cannot explain, not a hit."""
    z = np.asarray(m.z, dtype=float)
    hit = z[:, 0] < max_range
    through = np.zeros(len(z), dtype=bool)
    if grid is not None and len(z):
        wall = scan_walls(grid, pose, m, max_range)  # (computed ahead: ahead.py)
        tol = max(2.0 * grid.resolution, 0.05)  # a wall's own cell, and rounding
        through = hit & (z[:, 0] > wall + tol)
        hit &= ~through
        z = z.copy()
        z[:, 0] = np.where(through | ~hit, np.minimum(z[:, 0], wall), z[:, 0])
    # Python floats and bools from here: a scan's hundreds of beams, each a draw call.
    px = view.to_px(scan_segments(pose, Measurement(m.sensor, m.kind, z, m.beacon_ids))).tolist()
    hits, beyond = hit.tolist(), through.tolist()
    for (a, b), h, t in zip(px, hits, beyond, strict=True):
        if not h and not t:
            pygame.draw.line(surf, BEAM_NONE, a, b, width)
    for (a, b), t in zip(px, beyond, strict=True):
        if t:
            _dashed(surf, BEAM_BEYOND, a, b, max(width, 2))
            pygame.draw.circle(surf, BEAM_BEYOND, (round(b[0]), round(b[1])), max(3, width + 2), 2)
    for (a, b), h in zip(px, hits, strict=True):
        if h:
            pygame.draw.line(surf, BEAM_HIT, a, b, width)
    dot = max(2, width + 1)
    for (_, b), h in zip(px, hits, strict=True):
        if h:
            pygame.draw.circle(surf, BEAM_HIT, (round(b[0]), round(b[1])), dot)


def _dashed(surf: pygame.Surface, colour, a, b, width: int, on: float = 6.0, off: float = 4.0) -> None:
    """A dashed straight line from ``a`` to ``b`` [px] (in plain floats: a scan draws many)."""
    ax, ay = float(a[0]), float(a[1])
    dx, dy = float(b[0]) - ax, float(b[1]) - ay
    length = float(np.hypot(dx, dy))
    if not length > 0:
        return
    ux, uy = dx / length, dy / length
    t = 0.0
    while t < length:
        e = min(t + on, length)
        pygame.draw.line(surf, colour, (ax + ux * t, ay + uy * t), (ax + ux * e, ay + uy * e), width)
        t += on + off
