"""The filters' estimates in the world: an arrow at each mean, the 95 % ellipse of x-y and the
+-2 sigma heading wedge (lines on one another in stripes), a marker for a belief wider than
the world; the step view's prior ellipses and the best achievable ellipse (the PCRB).
"""

from __future__ import annotations

import math

import numpy as np
import pygame

from beacon_sim.app import palette, shapes
from beacon_sim.app.canvas import Canvas
from beacon_sim.app.strokes import polyline
from beacon_sim.app.view import View, ipx, world_rect
from beacon_sim.core.geometry import CHI2_2DOF, circle, covariance_ellipse
from beacon_sim.runs.styles import BOUND_STYLE

#: The 95 % ellipse of x-y: chi-square quantile for 2 degrees of freedom.
ELLIPSE_LEVEL = 0.95
ELLIPSE_SCALE2 = CHI2_2DOF[ELLIPSE_LEVEL]
#: The step view's prior (after predict): dashed, as in the textbook figures [px on, off].
PRIOR_DASH = (14, 10)


#: Outlines and axes already computed, by the bytes of their mean and covariance: a frame
#: draws each estimate's ellipse in the world and again in the magnifier, and asks its size
#: for the lost marker and the magnifier (the same numbers give the same outline).
_OUTLINES: dict[bytes, np.ndarray] = {}
_DIAMETERS: dict[bytes, float] = {}


def ellipse_outline(mean, cov) -> np.ndarray:
    """The 95 % ellipse of the x-y block of ``cov`` around ``mean``'s x-y, (96, 2) [m]
    (``core.geometry.covariance_ellipse``; do not change the array returned)."""
    m = np.asarray(mean, dtype=float)[:2]
    c = np.asarray(cov, dtype=float)[:2, :2]
    key = m.tobytes() + c.tobytes()
    pts = _OUTLINES.get(key)
    if pts is None:
        if len(_OUTLINES) > 256:
            _OUTLINES.clear()
        pts = _OUTLINES[key] = covariance_ellipse(m, c, ELLIPSE_SCALE2, 96)
    return pts


def ellipse_diameter(cov) -> float:
    """The major axis [m] of the 95 % ellipse of the x-y block of ``cov``."""
    c = np.asarray(cov, dtype=float)[:2, :2]
    key = c.tobytes()
    d = _DIAMETERS.get(key)
    if d is None:
        if len(_DIAMETERS) > 256:
            _DIAMETERS.clear()
        d = _DIAMETERS[key] = (math.inf if not np.all(np.isfinite(c)) else
                               2.0 * math.sqrt(max(float(np.linalg.eigvalsh(c)[-1]), 0.0) * ELLIPSE_SCALE2))
    return d


class EstimateLayer(Canvas):
    """Estimates (arrows, ellipses, wedges, lost markers), the step view's priors, the bound."""

    def estimates(self, surf, view: View, estimates, colours, dashes, radius: float,
                  ellipses: bool = True, arrow: float = 1.0, wedges: bool = True) -> None:
        """Estimates ``(key, mean, cov)``: an arrow each in ``colours[key]`` (``arrow`` times
        the usual size), then (with ``ellipses``) the 95 % ellipses and (with ``wedges``)
        heading wedges in ``dashes[key]`` style, solid ones first: a dashed one drawn over a
        solid one leaves gaps to see it through."""
        for key, mean, _ in estimates:
            self._arrow(surf, view, mean, colours[key], radius, arrow)
        if ellipses:
            order = sorted(estimates, key=lambda e: dashes.get(e[0]) is not None)
            if wedges:  # every wedge first: a small ellipse is never under a wedge
                for key, mean, cov in order:
                    self.uncertainty(surf, view, mean, cov, colours[key], dashes.get(key), radius,
                                     wedge=True, ellipse=False)
            xmin, ymin, xmax, ymax = view.bounds
            too_big = math.hypot(xmax - xmin, ymax - ymin)  # a 95 % ellipse wider than the world
            self._lost_labels: list[pygame.Rect] = []
            shown = []
            for key, mean, cov in order:
                across = ellipse_diameter(cov)
                if not across <= too_big:  # lost (or not a number): a marker, not lines
                    self.lost_marker(surf, view, key, mean, across, colours[key], dashes.get(key))
                else:
                    shown.append((key, mean, cov))
            self._ellipses(surf, view, shown, colours, dashes)

    def _ellipses(self, surf, view: View, estimates, colours, dashes) -> None:
        """The 95 % ellipses of ``estimates`` (solid ones first). Ellipses that lie on one
        another (every point within a line width) are drawn in stripes, each colour in turn
        along the outline and an equal share of it, with a note naming them: one drawn over
        the other hid it (a dashed one left the other only its gaps)."""
        lw = self.lw
        outlines = [view.to_px(ellipse_outline(mean, cov)) for _, mean, cov in estimates]
        groups: list[list[int]] = []
        for i in range(len(estimates)):
            if np.all(np.isfinite(outlines[i])):
                for g in groups:
                    if np.max(np.hypot(*(outlines[g[0]] - outlines[i]).T)) <= lw:
                        g.append(i)
                        break
                else:
                    groups.append([i])
        striped = {i: (g.index(i), len(g)) for g in groups if len(g) > 1 for i in g}
        for i, (key, mean, cov) in enumerate(estimates):
            if i not in striped:
                self.uncertainty(surf, view, mean, cov, colours[key], dashes.get(key), 0.0, wedge=False)
        for g in groups:
            if len(g) < 2:
                continue
            pts = outlines[g[0]]
            seg = 3.0 * lw
            arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
            polyline(surf, colours[estimates[g[0]][0]], pts, lw, None, closed=True)
            for k, i in enumerate(g[1:]):
                # the same outline in stripes over the first, each started a stripe further
                # on: the colours take turns (two: exactly, half and half)
                start = int(np.searchsorted(arc, (k * seg) % max(arc[-1], 1e-9)))
                polyline(surf, colours[estimates[i][0]], np.roll(pts, -start, axis=0), lw,
                         (seg, (len(g) - 1) * seg), closed=True)
            if max(np.ptp(pts[:, 0]), np.ptp(pts[:, 1])) < 80:  # under the robot: the magnifier's
                continue
            names = ", ".join(estimates[i][0] for i in g)
            img = self.text(f"{names}: same ellipse", "small", palette.TEXT)
            top = pts[int(np.argmin(pts[:, 1]))]
            box = img.get_rect(midbottom=(ipx(top[0]), ipx(top[1]) - lw - 2)).inflate(8, 2)
            box.clamp_ip(surf.get_clip())
            surf.fill(palette.PANEL, box)
            surf.blit(img, img.get_rect(center=box.center))

    def lost_marker(self, surf, view: View, key: str, mean, across: float, colour, dash) -> None:
        """A belief whose 95 % ellipse is wider than the world (``across`` [m]): instead of
        lines crossing the world and its margins, a ring at the estimate (kept inside the
        world) with four ticks pointing out, and a label beside it that keeps off the other
        such labels: "dead_reckoning: 95 % ellipse 16 m, wider than the world"."""
        xmin, ymin, xmax, ymax = view.bounds
        at = np.array([min(max(float(mean[0]), xmin), xmax), min(max(float(mean[1]), ymin), ymax)])
        c = view.to_px(at) if np.all(np.isfinite(at)) else view.to_px(np.array([xmin, ymax]))
        r = 22.0
        ring = circle(np.asarray(c, dtype=float), r, 48)
        polyline(surf, colour, ring, self.lw, dash, closed=True)
        for a in (0.25, 0.75, 1.25, 1.75):  # ticks pointing out: the belief goes on beyond
            d = np.array([math.cos(a * math.pi), math.sin(a * math.pi)])
            pygame.draw.line(surf, colour, c + d * (r + 3), c + d * (r + 13), max(self.lw - 1, 2))
        size = f"{across:.0f} m, wider than the world" if math.isfinite(across) else "not a number"
        img = self.text(f"{key}: 95 % ellipse {size}", "small", palette.TEXT)
        clip = surf.get_clip()
        taken = self._lost_labels
        cx, cy, step = ipx(c[0]), ipx(c[1]), img.get_height() + 8
        box = None
        world = world_rect(view)
        for k in range(4):  # first in the margins above and under the world: it hides nothing
            spot = img.get_rect(midbottom=(cx, world.top - 8 - k * step)) if k % 2 == 0 \
                else img.get_rect(midtop=(cx, world.bottom + 30 + (k // 2) * step))
            spot = spot.inflate(10, 4)
            spot.clamp_ip(pygame.Rect(world.left, clip.top, world.width, clip.height).clip(clip))
            if clip.contains(spot) and not spot.colliderect(world) and spot.collidelist(taken) < 0:
                box = spot
                break
        for k in range(12 if box is None else 0):  # beside the ring (right, left), further down, up
            dy = (k // 2 + 1) // 2 * step * (1 if (k // 2) % 2 else -1)
            spot = img.get_rect(midleft=(cx + ipx(r) + 18, cy + dy)) if k % 2 == 0 \
                else img.get_rect(midright=(cx - ipx(r) - 18, cy + dy))
            spot = spot.inflate(10, 4)
            if clip.contains(spot) and spot.collidelist(taken) < 0:
                box = spot
                break
        if box is None:
            box = img.get_rect(midleft=(cx + ipx(r) + 18, cy)).inflate(10, 4)
            box.clamp_ip(clip)
        taken.append(box)
        surf.fill(palette.PANEL, box)
        pygame.draw.rect(surf, colour, box, 2)
        surf.blit(img, img.get_rect(center=box.center))

    def _arrow(self, surf, view: View, mean, colour, radius: float, scale: float = 1.0) -> None:
        """The estimated pose: a filled arrow in the filter's colour, outlined in black."""
        size = max(1.2 * radius, 16.0 / view.scale) * scale
        tri = view.to_px(shapes.arrow(mean, size))
        pygame.draw.polygon(surf, colour, tri)
        pygame.draw.polygon(surf, palette.TEXT, tri, 2)

    def uncertainty(self, surf, view: View, mean, cov, colour, dash, radius: float,
                    width: int | None = None, wedge: bool = True, ellipse: bool = True) -> None:
        """The 95 % ellipse of x-y (``ellipse``) and the +-2 sigma heading wedge (``wedge``),
        in ``dash`` style."""
        lw = width or self.lw
        if ellipse:
            pts = view.to_px(ellipse_outline(mean, cov))
            if np.all(np.isfinite(pts)) and np.ptp(pts[:, 0]) < 1e5 and np.ptp(pts[:, 1]) < 1e5:
                polyline(surf, colour, pts, lw, dash, closed=True)
        if not wedge:
            return
        sigma = math.sqrt(max(float(cov[2, 2]), 0.0))
        r = max(3.2 * radius, 55.0 / view.scale)
        w = view.to_px(shapes.wedge(mean, 2.0 * sigma, r))
        polyline(surf, colour, w, max(lw - 1, 2), dash, closed=True)

    def priors(self, surf, view: View, steps: dict, colours, used_ids: set[int]) -> None:
        """The step view: for each filter the 95 % ellipse after predict (the prior, dashed,
        thinner) and a line from the prior's mean to the posterior's (what the update
        moved), and a black ring around each beacon the update used. The posterior itself is
        drawn solid by the normal pass, over this."""
        lw = max(self.lw - 1, 2)
        for name, ((m0, c0), (m1, _)) in steps.items():
            colour = colours[name]
            pts = view.to_px(covariance_ellipse(m0[:2], c0[:2, :2], ELLIPSE_SCALE2, 96))
            if np.all(np.isfinite(pts)) and np.ptp(pts[:, 0]) < 1e5 and np.ptp(pts[:, 1]) < 1e5:
                polyline(surf, colour, pts, lw, PRIOR_DASH, closed=True)
            a, b = view.to_px(np.array([m0[:2], m1[:2]]))
            pygame.draw.line(surf, colour, a, b, 2)
            pygame.draw.circle(surf, colour, (ipx(a[0]), ipx(a[1])), 6, 2)
        world = self.last_world
        if world is not None and used_ids:
            for bcn, (x, y) in zip(world.beacons, view.to_px(world.beacon_xy), strict=True):
                if bcn.id in used_ids:
                    pygame.draw.circle(surf, palette.TEXT, (ipx(x), ipx(y)), 24, 4)

    def bound(self, surf, view: View, pose, P) -> None:
        """The best achievable 95 % ellipse (the PCRB ``P`` (3, 3)) around the TRUE pose,
        black and dotted: no unbiased filter's ellipse can be smaller."""
        colour, dash = BOUND_STYLE
        pts = view.to_px(covariance_ellipse(np.asarray(pose)[:2], np.asarray(P)[:2, :2],
                                            ELLIPSE_SCALE2, 96))
        if np.all(np.isfinite(pts)) and np.ptp(pts[:, 0]) < 1e5 and np.ptp(pts[:, 1]) < 1e5:
            polyline(surf, colour, pts, max(self.lw - 1, 2), dash, closed=True)
