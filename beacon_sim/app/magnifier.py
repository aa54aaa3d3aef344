"""The magnifier: an inset at a corner of the world that shows, much closer, the estimates
whose 95 % ellipse is smaller than the robot on screen (a converged filter's centimetres),
with a scale bar, each ellipse's size in words and, when small too, the bound's.
"""

from __future__ import annotations

import math

import numpy as np
import pygame

from beacon_sim.app import palette
from beacon_sim.app.estimate_layer import ELLIPSE_SCALE2, EstimateLayer, ellipse_diameter
from beacon_sim.app.strokes import draw_cross, polyline
from beacon_sim.app.view import View, ipx, nice_step, world_rect
from beacon_sim.core.geometry import covariance_ellipse
from beacon_sim.runs.styles import BOUND_STYLE

#: The magnifier's words above the sizes of the ellipses it shows.
MAGNIFIER_HEADING = "95 % ellipse, across:"
MAGNIFIER_BOUND = "best possible (PCRB)"
#: Below this size [px] in the magnifier the bound gets its own closer look (a box inside).
MIN_BOUND_PX = 30.0


def format_length(metres: float) -> str:
    """``4 cm``, ``0.5 mm``, ``1.2 m``: a length in the unit that reads best."""
    if metres >= 1.0:
        return f"{metres:.2g} m"
    if metres >= 0.01:
        return f"{metres * 100:.2g} cm"
    return f"{metres * 1000:.2g} mm"


def alike_keys(small) -> list[str]:
    """The names of the largest group of ``(key, mean, cov, across)`` whose 95 % ellipses
    lie on one another (every point within 2 % of the largest's size): the inset draws
    them in stripes under the note "kf, ekf: same ellipse", which must fit its width."""
    best: list[str] = []
    outlines = [covariance_ellipse(m[:2], c[:2, :2], ELLIPSE_SCALE2, 48) for _, m, c, _ in small]
    for i, (*_rest, across) in enumerate(small):
        group = [k for j, (k, *_r, a) in enumerate(small)
                 if np.max(np.hypot(*(outlines[j] - outlines[i]).T)) <= 0.02 * max(a, across)]
        if len(group) > 1 and len(group) > len(best):
            best = group
    return best


class Magnifier(EstimateLayer):
    """The inset; ``last_magnifier`` says what it drew, ``bound_cov`` is the bound it shows."""

    def __init__(self, fonts: dict[str, pygame.font.Font]):
        super().__init__(fonts)
        self.last_magnifier: dict | None = None  # what the magnifier drew (see magnifier)
        # the live PCRB (3, 3) the window shows (B), or None: the magnifier draws it too
        self.bound_cov: np.ndarray | None = None

    def magnifier(self, surf, view: View, pose, estimates, colours, dashes, radius: float) -> None:
        """A magnified inset (at a corner of the world, see below) when an estimate's 95 % ellipse is
        smaller than the robot's outline on screen (a converged KF's 2 cm lie inside it):
        the true position (black cross), those estimates (dot) and their ellipses at a
        zoom where the largest is about half the inset, a scale bar, and each ellipse's size
        in words. A frame marks the magnified part around the robot. ``last_magnifier``
        holds what was drawn (for tests): rect (the inset), block (with its strip of words),
        px per metre, {name: ellipse across [px]},
        and the bound's across [px] (``bound_px``) when ``bound_cov`` is shown and small (a
        map world's bound is millimetres)."""
        r_px = max(radius, 14.0 / view.scale) * view.scale
        small = []
        for key, mean, cov in estimates:
            axis = ellipse_diameter(cov)  # the 95 % ellipse's major axis [m]
            if math.isfinite(axis) and axis * view.scale < 2.0 * r_px:
                small.append((key, mean, cov, axis))
        b_axis = ellipse_diameter(self.bound_cov) if self.bound_cov is not None else math.nan
        with_bound = math.isfinite(b_axis) and b_axis * view.scale < 2.0 * r_px
        if not small and not with_bound:
            return
        area = pygame.Rect(view.area)
        font = self.fonts["small"]
        lh = font.get_linesize()
        # wide enough for its words (the bar is at most half the width, its length beside it)
        alike = alike_keys(small)
        floor = max(150, font.size(MAGNIFIER_HEADING)[0] + 24, 2 * (font.size("50 mm")[0] + 26),
                    max((font.size(f"{key}  99 mm")[0] for key, *_ in small), default=0) + 50,
                    font.size(f"{MAGNIFIER_BOUND}  99 mm")[0] + 50 if with_bound else 0,
                    font.size(f"{', '.join(alike)}: same ellipse")[0] + 16 if alike else 0)
        strip_h = lh * (len(small) + with_bound + 3) + 10
        robot_px = view.to_px(np.asarray(pose[:2], dtype=float))
        robot_box = pygame.Rect(ipx(robot_px[0] - r_px) - 8, ipx(robot_px[1] - r_px) - 8,
                                ipx(2 * r_px) + 16, ipx(2 * r_px) + 16)
        room = world_rect(view)
        # the beacons and their labels, and the labels of beliefs wider than the world
        beacons = [*self.beacon_rects, *getattr(self, "_lost_labels", ())]

        def hidden(b: pygame.Rect) -> tuple[bool, int]:
            return b.colliderect(robot_box), len(b.collidelistall(beacons))

        # The place that hides the least: never the robot, then the fewest beacons and labels;
        # then the largest inset (its full size, then smaller, down to its words'
        # width, before it hides a beacon); then a corner (top right first) before the middle
        # of an edge; then the least of the room (the world's bounds): the margins first.
        best: tuple | None = None
        full = max(min(int(0.3 * min(area.width, area.height)), 360), floor)
        for rank, side in enumerate(dict.fromkeys((full, (full + floor) // 2, floor))):
            tall = side + strip_h + 2
            corners = [pygame.Rect(area.right - side - 12, area.top + 12, side, tall),
                       pygame.Rect(area.right - side - 12, area.bottom - tall - 12, side, tall),
                       pygame.Rect(area.left + 12, area.top + 40, side, tall),
                       pygame.Rect(area.left + 12, area.bottom - tall - 12, side, tall)]
            edges = [pygame.Rect(area.centerx - side // 2, area.top + 12, side, tall),
                     pygame.Rect(area.centerx - side // 2, area.bottom - tall - 12, side, tall),
                     pygame.Rect(area.left + 12, area.centery - tall // 2, side, tall),
                     pygame.Rect(area.right - side - 12, area.centery - tall // 2, side, tall)]
            for order, b in enumerate(corners + edges):
                over = b.clip(room)
                key = (*hidden(b), rank, order >= len(corners), over.width * over.height, order)
                if best is None or key < best[0]:
                    best = (key, b, side)
            if best is not None and best[0][:2] == (False, 0):
                break  # free at this size: no smaller one
        assert best is not None
        _, block, side = best
        rect = pygame.Rect(block.left, block.top, side, side)
        # the zoom: the largest small ellipse (or the spread of the means) half the inset
        centre = np.asarray(pose[:2], dtype=float)
        reach = max(max((a for *_, a in small), default=0.0) / 2.0,
                    max((float(np.hypot(*(m[:2] - centre))) for _, m, _, _ in small), default=0.0),
                    b_axis / 2.0 if with_bound else 0.0, 1e-4)
        scale = min(0.25 * side / reach, 1e6)
        if scale < 4.0 * view.scale:  # not worth a magnifier
            return
        sub = View(view.bounds, (rect.left, rect.top, rect.width, rect.height))
        sub.scale, sub.centre = scale, centre
        # where the inset looks, marked on the map
        half = 0.5 * side / scale
        a, b = view.to_px(np.array([[centre[0] - half, centre[1] + half],
                                    [centre[0] + half, centre[1] - half]]))
        mark = pygame.Rect(ipx(a[0]), ipx(a[1]), max(ipx(b[0] - a[0]), 3), max(ipx(b[1] - a[1]), 3))
        pygame.draw.rect(surf, palette.TEXT, mark.inflate(6, 6), 2)
        pygame.draw.line(surf, palette.TEXT_DIM, mark.inflate(6, 6).topright, rect.bottomleft, 1)
        old_clip = surf.get_clip()
        surf.fill(palette.BACKGROUND, rect)
        surf.set_clip(rect)
        step = nice_step(scale, side / 5)
        g0 = np.floor((centre - half) / step) * step
        for k in range(int(2 * half / step) + 2):
            x, y = sub.to_px(g0 + k * step)
            pygame.draw.line(surf, palette.GRID_MINOR, (ipx(x), rect.top), (ipx(x), rect.bottom), 1)
            pygame.draw.line(surf, palette.GRID_MINOR, (rect.left, ipx(y)), (rect.right, ipx(y)), 1)
        c = sub.to_px(centre)
        draw_cross(surf, c, 8, palette.ROBOT, 3)
        if with_bound:
            self.bound(surf, sub, pose, self.bound_cov)
        lw = max(self.lw - 1, 2)
        drawn = {}
        solid_first = sorted(small, key=lambda e: dashes.get(e[0]) is not None)
        for key, mean, _, axis in solid_first:
            m = sub.to_px(mean[:2])
            pygame.draw.circle(surf, colours[key], (ipx(m[0]), ipx(m[1])), lw + 1)
            drawn[key] = axis * scale
        # as on the map: ellipses that lie on one another in stripes (the KF's and the EKF's
        # 9 cm alike: one drawn over the other hid it), at the inset's line width
        world_lw, self.lw = self.lw, lw
        try:
            self._ellipses(surf, sub, [(key, mean, cov) for key, mean, cov, _ in solid_first],
                           colours, dashes)
        finally:
            self.lw = world_lw
        bound_zoom = None
        if with_bound and b_axis * scale < MIN_BOUND_PX:  # too small at this zoom: a closer look
            bound_zoom = self._bound_inset(surf, sub, rect, pose, b_axis,
                                           [(key, mean) for key, mean, *_ in small], colours)
        surf.set_clip(old_clip)
        pygame.draw.rect(surf, palette.TEXT, rect, 2)
        # the scale bar and the sizes, on a strip along the inset's bottom
        font_key = "small"
        bar_m = nice_step(scale, side / 4)
        bar_px = bar_m * scale
        y = rect.bottom + 6
        strip = pygame.Rect(rect.left, rect.bottom + 2, rect.width, strip_h)
        surf.fill(palette.PANEL, strip)
        pygame.draw.rect(surf, palette.PANEL_EDGE, strip, 1)
        x0 = rect.left + 10
        pygame.draw.line(surf, palette.TEXT, (x0, y + lh // 2), (ipx(x0 + bar_px), y + lh // 2), 4)
        surf.blit(self.text(format_length(bar_m), font_key, palette.TEXT), (ipx(x0 + bar_px) + 8, y))
        y += lh
        surf.blit(self.text(f"zoom x{scale / view.scale:.0f}", font_key, palette.TEXT), (x0, y))
        y += lh
        surf.blit(self.text(MAGNIFIER_HEADING, font_key, palette.TEXT_DIM), (x0, y))
        for key, *_rest, axis in small:
            y += lh
            t = self.text(f"{key}  {format_length(axis)}", font_key, palette.TEXT)
            pygame.draw.line(surf, colours[key], (x0, y + lh // 2), (x0 + 18, y + lh // 2), 5)
            surf.blit(t, (x0 + 26, y))
        if with_bound:
            y += lh
            colour, dash = BOUND_STYLE
            polyline(surf, colour, np.array([[x0, y + lh // 2], [x0 + 18, y + lh // 2]], dtype=float),
                     3, dash)
            surf.blit(self.text(f"{MAGNIFIER_BOUND}  {format_length(b_axis)}", font_key, palette.TEXT),
                      (x0 + 26, y))
        self.last_magnifier = {"rect": rect, "block": rect.union(strip), "scale": scale, "across_px": drawn,
                               "bound_px": b_axis * scale if with_bound else None,
                               "bound_zoom": bound_zoom}

    def _bound_inset(self, surf, sub: View, rect: pygame.Rect, pose, b_axis: float, means,
                     colours) -> float:
        """A second look inside the magnifier (its bottom-left corner) at the bound alone,
        when it is too small at the magnifier's zoom (a map world's millimetres beside a
        filter's centimetres): the true position, the bound's ellipse across 60 % of the box,
        the estimates' means that fall inside. Returns its zoom over the magnifier's."""
        side = max(rect.width * 2 // 5, 100)
        box = pygame.Rect(rect.left + 6, rect.bottom - side - 6, side, side)
        scale = 0.6 * side / max(b_axis, 1e-6)
        view = View(sub.bounds, (box.left, box.top, box.width, box.height))
        view.scale, view.centre = scale, np.asarray(pose[:2], dtype=float)
        clip = surf.get_clip()
        surf.fill(palette.BACKGROUND, box)
        surf.set_clip(box.clip(clip))
        draw_cross(surf, view.to_px(view.centre), 4, palette.ROBOT, 2)
        self.bound(surf, view, pose, self.bound_cov)
        for key, mean in means:
            m = view.to_px(np.asarray(mean[:2], dtype=float))
            if box.collidepoint(ipx(m[0]), ipx(m[1])):
                pygame.draw.circle(surf, colours[key], (ipx(m[0]), ipx(m[1])), 4)
        zoom = scale / sub.scale
        surf.blit(self.text(f"x{zoom:.0f} more", "small", palette.TEXT_DIM), (box.left + 4, box.top + 2))
        surf.set_clip(clip)
        pygame.draw.rect(surf, palette.TEXT, box, 1)
        return zoom
