"""Strokes in pixels: the line width for a window's height, thick polylines (solid or dashed,
with round caps only where pygame leaves a notch) and crosses. Every layer of the window
draws its lines with these; they know nothing of metres (``view`` converts).
"""

from __future__ import annotations

import math

import numpy as np
import pygame

from beacon_sim.app.view import ipx


def line_width(height_px: int) -> int:
    """Belief line width [px] for a window ``height_px`` tall: 4 px at 800, more above."""
    return max(4, round(height_px / 200))


def polyline(surf, colour, pts, width: int, dash=None, closed: bool = False) -> None:
    """A thick polyline through ``pts`` (k, 2) [px], solid (``dash`` None) or dashed with
    the pattern ``dash`` (px on, px off, ...), measured along the line."""
    pts = np.asarray(pts, dtype=float)
    if closed:
        pts = np.vstack([pts, pts[:1]])
    if len(pts) < 2:
        return
    if dash is None:
        pygame.draw.lines(surf, colour, False, pts, width)
        if len(pts) > 200:
            return
        # Round joints: thick pygame lines leave notches at corners. A thick line is drawn as
        # 1 px lines side by side, offset along x or along y by its slope, so a notch is left
        # where the line turns or where the offset's axis changes; elsewhere (most vertices of
        # a 96-point ellipse) the next segment covers the joint and no circle is drawn.
        for x, y in pts[1:-1][notched_joints(pts)].tolist():
            pygame.draw.circle(surf, colour, (ipx(x), ipx(y)), max(width // 2 - 1, 1))
        return
    seg = np.hypot(*np.diff(pts, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    total = float(s[-1])
    if not total > 0:
        return
    step = max(total / 4000.0, 1.5)  # sample every ~2 px (at most 4000 samples)
    t = np.arange(0.0, total + step, step)
    t[-1] = min(t[-1], total)
    xs, ys = np.interp(t, s, pts[:, 0]), np.interp(t, s, pts[:, 1])
    period = float(sum(dash))
    bounds = np.cumsum(dash)
    phase = np.searchsorted(bounds, t % period, side="right")
    on = phase % 2 == 0
    edges = np.flatnonzero(np.diff(np.concatenate([[0], on.astype(np.int8), [0]]))).tolist()
    xy = np.stack([xs, ys], 1).tolist()  # one conversion, then slices (no array per dash)
    r = max(width // 2, 1)
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        if b - a >= 2:
            pygame.draw.lines(surf, colour, False, xy[a:b], width)
        else:
            pygame.draw.circle(surf, colour, xy[a], r)


#: A joint turning by more than this [rad] gets a round cap (see :func:`polyline`).
JOINT_TURN = math.radians(8.0)


def notched_joints(pts: np.ndarray) -> np.ndarray:
    """Which interior vertices of the polyline ``pts`` (k, 2) [px] a thick pygame line leaves
    a notch at: a turn of more than ``JOINT_TURN``, or the segments on either side drawn
    with their 1 px strokes offset along different axes (one steeper than 45 degrees, one
    not). Zero-length segments count as turns. Returns a boolean mask of k - 2 entries."""
    d = np.diff(pts, axis=0)
    a, b = d[:-1], d[1:]
    cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    dot = (a * b).sum(axis=1)
    turn = np.abs(np.arctan2(cross, dot))
    steep = np.abs(d[:, 1]) > np.abs(d[:, 0])
    degenerate = ~((a != 0).any(axis=1) & (b != 0).any(axis=1))
    return (turn > JOINT_TURN) | (steep[:-1] != steep[1:]) | degenerate


def draw_cross(surf, at, r: int, colour, width: int) -> None:
    """An x of half-size ``r`` [px] centred on the pixel ``at``."""
    x, y = ipx(at[0]), ipx(at[1])
    pygame.draw.line(surf, colour, (x - r, y - r), (x + r, y + r), width)
    pygame.draw.line(surf, colour, (x - r, y + r), (x + r, y - r), width)
