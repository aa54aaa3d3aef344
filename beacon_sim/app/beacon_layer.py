"""The beacons in the world: a square each with its ID placed where it hides no other beacon
or label, on a green disc when seen this tick, in a dashed ring when in a sensor's range but
missed (``in_view.missed_ids``).
"""

from __future__ import annotations

import numpy as np
import pygame

from beacon_sim.app import palette
from beacon_sim.app.canvas import Canvas
from beacon_sim.app.strokes import polyline
from beacon_sim.app.view import View, ipx
from beacon_sim.core.geometry import circle

#: A beacon in a sensor's range that was not detected: a dashed ring [px on, off].
MISSED_DASH = (6, 5)


class BeaconLayer(Canvas):
    """Draws the beacons and remembers where they and their labels are (``beacon_rects``)."""

    def beacons(self, surf, view: View, world, seen, missed=frozenset()) -> None:
        """Every beacon as a square with its ID; those in ``seen`` (IDs) on a green disc, those
        in ``missed`` (in a sensor's range and field of view, not detected) in a dashed
        vermillion ring."""
        pxs = [(ipx(x), ipx(y)) for x, y in view.to_px(world.beacon_xy)]
        half = 9
        squares = [pygame.Rect(x - half, y - half, 2 * half, 2 * half) for x, y in pxs]
        for bcn, (x, y), rect in zip(world.beacons, pxs, squares, strict=True):
            if bcn.id in seen:
                pygame.draw.circle(surf, palette.BEACON_SEEN, (x, y), half + 7)
                pygame.draw.circle(surf, palette.BEACON_SEEN_RING, (x, y), half + 7, 3)
            elif bcn.id in missed:
                ring = circle(np.array([x, y], dtype=float), half + 8, 40)
                polyline(surf, palette.WARN, ring, 3, MISSED_DASH, closed=True)
            pygame.draw.rect(surf, palette.BEACON, rect)
            pygame.draw.rect(surf, palette.BACKGROUND, rect.inflate(-8, -8))
        # Labels: top-right of the beacon unless that hides another beacon or label (real
        # data sets have beacons in close pairs); then the next free corner.
        placed: list[pygame.Rect] = []
        for bcn, (x, y) in zip(world.beacons, pxs, strict=True):
            t = self.text(str(bcn.id), "label", palette.TEXT)
            w, h = t.get_width(), t.get_height()
            corners = [(x + half + 6, y - half - h + 6), (x + half + 6, y + half - 6),
                       (x - half - 6 - w, y - half - h + 6), (x - half - 6 - w, y + half - 6),
                       (x - w // 2, y - half - h - 4), (x - w // 2, y + half + 4),
                       (x + half + 6 + w, y - h // 2), (x - half - 6 - 2 * w, y - h // 2)]
            rects = [pygame.Rect(cx, cy, w, h) for cx, cy in corners]
            at = next((r for r in rects if r.collidelist(placed) < 0 and r.collidelist(squares) < 0
                       and r.inflate(4, 0).collidelist(self.axis_rects) < 0),
                      next((r for r in rects if r.collidelist(placed) < 0
                            and r.collidelist(squares) < 0), rects[0]))
            placed.append(at)
            surf.fill(palette.BACKGROUND, at.inflate(6, -2))
            surf.blit(t, at)
        self.beacon_rects = squares + placed
