"""What the window draws for beacons that give distances (docs/distance_beacons.md): the
circle of each range and the curve of each range difference through the robot, the
trilaterated fix with its 95 % HDOP ellipse, and (key O) the floor shaded by the HDOP of
the beacon layout, with its colour key. The geometry is core/distance_curves.py's and
core/trilateration.py's, in metres; here it becomes pixels."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pygame

from beacon_sim.app import palette
from beacon_sim.app.ahead import tdoa_curves, tdoa_fix
from beacon_sim.core.distance_curves import floor_hdop, range_circle
from beacon_sim.core.geometry import covariance_ellipse
from beacon_sim.core.metrics import chi2_quantile
from beacon_sim.core.trilateration import TrilaterationError, fix_covariance

#: The kinds drawn here.
DISTANCE_KINDS = ("range", "tdoa", "tdoa_fix")

CURVE = (0, 114, 178)         # Okabe-Ito blue: a range's circle, a difference's curve
FIX = (204, 121, 167)         # Okabe-Ito reddish purple: the trilaterated fix and its ellipse
#: HDOP colour key: the tints of the bands, from the best HDOP in view to 5x it.
HDOP_TINTS = ((225, 245, 225), (205, 235, 205), (250, 240, 200), (250, 215, 180), (240, 185, 185))
#: Each band starts at this multiple of the best HDOP in view.
HDOP_STEPS = (1.0, 1.5, 2.0, 3.0, 5.0)
_SCALE95 = chi2_quantile(0.95, 2)


def distance_sensor(sensors):
    """The first sensor of a distance kind, or None."""
    return next((s for s in sensors if s.kind in DISTANCE_KINDS), None)


def readings(surf, view, world, sensors, pose, measurements, lw: int, polyline) -> None:
    """The circles / curves of this tick's distance readings and the fix with its ellipse."""
    reach = 1.5 * math.hypot(world.width, world.height)
    for m in measurements:
        if m.kind not in DISTANCE_KINDS or not len(m):
            continue
        spec = next((s for s in sensors if s.name == m.sensor), None)
        if spec is None:
            continue
        h = spec.beacon_height
        bxy = world.beacon_positions(m.beacon_ids)
        if m.kind == "range":
            for b, r in zip(bxy, m.z[:, 0], strict=True):
                ring = range_circle(b, float(r), h)
                if ring is not None:
                    polyline(surf, CURVE, view.to_px(ring), 2, None, closed=True)
            continue
        if m.kind == "tdoa":
            for curve in tdoa_curves(m, bxy, h, pose, reach):  # (computed ahead: ahead.py)
                if curve is not None and len(curve) > 1:
                    polyline(surf, CURVE, view.to_px(curve), 2, None)
            fix = tdoa_fix(m, bxy, h, spec.noise.range_std)  # (computed ahead: ahead.py)
            if fix is None:
                continue
            xy, cov = fix.xy, fix.cov
        else:
            xy = np.asarray(m.z[0], dtype=float)
            try:
                cov = fix_covariance(xy, bxy[0], bxy[1:], h, spec.noise.range_std)
            except TrilaterationError:
                continue
        _fix(surf, view, xy, cov, lw, polyline)


def _fix(surf, view, xy, cov, lw: int, polyline) -> None:
    at = view.to_px(xy)
    r = 8
    pygame.draw.line(surf, FIX, (at[0] - r, at[1] - r), (at[0] + r, at[1] + r), 3)
    pygame.draw.line(surf, FIX, (at[0] - r, at[1] + r), (at[0] + r, at[1] - r), 3)
    pts = view.to_px(covariance_ellipse(xy, cov, _SCALE95, 72))
    if np.all(np.isfinite(pts)) and np.ptp(pts[:, 0]) < 1e5:
        polyline(surf, FIX, pts, max(lw - 1, 2), (10, 6), closed=True)


class HdopShading:
    """The floor tinted by the HDOP of a fix from every beacon (kept while the view and the
    window do not change)."""

    def __init__(self) -> None:
        self._key: tuple | None = None
        self._tint: pygame.Surface | None = None
        self.edges: tuple[float, ...] = ()   # where each band starts (HDOP), last drawn

    def draw(self, surf, view, world, sensors, rect: pygame.Rect) -> None:
        """Tint ``rect`` (the world's part of the window, px) by the HDOP at each point."""
        spec = distance_sensor(sensors)
        if spec is None or not len(world.beacons) or rect.width <= 0 or rect.height <= 0:
            return
        key = (view.key, tuple(rect), spec.kind, spec.beacon_height, id(world))
        if key != self._key:
            self._key = key
            self._tint = self._make(view, world, spec, rect)
        if self._tint is not None:
            surf.blit(self._tint, rect, special_flags=pygame.BLEND_RGB_MULT)

    def _make(self, view, world, spec, rect: pygame.Rect) -> pygame.Surface:
        x0, y1 = view.to_world((rect.left, rect.top))
        x1, y0 = view.to_world((rect.right, rect.bottom))
        nx = max(8, rect.width // 6)
        ny = max(8, rect.height // 6)
        _, _, val = floor_hdop(spec.kind, (x0, y0, x1, y1), world.beacon_xy, spec.beacon_height, nx, ny)
        finite = val[np.isfinite(val)]
        best = float(finite.min()) if finite.size else 1.0
        self.edges = tuple(float(f"{best * k:.2g}") for k in HDOP_STEPS)
        rgb = np.empty((ny, nx, 3), dtype=np.uint8)
        rgb[:] = HDOP_TINTS[0]
        for lo, colour in zip(self.edges, HDOP_TINTS, strict=True):
            rgb[val >= lo] = colour
        rgb[~np.isfinite(val)] = HDOP_TINTS[-1]
        small = pygame.surfarray.make_surface(np.ascontiguousarray(rgb[::-1].transpose(1, 0, 2)))
        return pygame.transform.scale(small, rect.size)

    def key_box(self, surf, world_rect: pygame.Rect, font, kind: str) -> None:
        """The colour key, bottom left of the world: each band's tint and its HDOP range."""
        if not self.edges:
            return
        label = "HDOP of a TDOA fix" if kind in ("tdoa", "tdoa_fix") else "HDOP of a range fix"
        head = font.render(label, True, palette.TEXT)
        e = self.edges
        texts = [f"{lo:g} - {hi:g}" for lo, hi in itertools.pairwise(e)] + [f"> {e[-1]:g}"]
        rendered = [font.render(t, True, palette.TEXT) for t in texts]
        w = max(s.get_width() for s in [head, *rendered]) + 34
        hgt = head.get_height() + sum(s.get_height() + 2 for s in rendered) + 12
        box = pygame.Rect(world_rect.left + 10, world_rect.bottom - hgt - 10, w, hgt)
        pygame.draw.rect(surf, palette.PANEL, box)
        pygame.draw.rect(surf, palette.PANEL_EDGE, box, 1)
        y = box.top + 4
        surf.blit(head, (box.left + 6, y))
        y += head.get_height() + 2
        for colour, text in zip(HDOP_TINTS, rendered, strict=True):
            sw = pygame.Rect(box.left + 6, y + 2, 18, text.get_height() - 4)
            pygame.draw.rect(surf, colour, sw)
            pygame.draw.rect(surf, palette.PANEL_EDGE, sw, 1)
            surf.blit(text, (box.left + 28, y))
            y += text.get_height() + 2


__all__ = ["DISTANCE_KINDS", "HdopShading", "distance_sensor", "readings"]
