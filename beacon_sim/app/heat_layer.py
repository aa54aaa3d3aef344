"""A grid filter's belief in the world: a translucent heat map in the filter's colour, made
once per tick and view and kept.
"""

from __future__ import annotations

import math

import numpy as np
import pygame

from beacon_sim.app.canvas import Canvas
from beacon_sim.app.view import View, ipx
from beacon_sim.filters.base import GridBelief


class HeatLayer(Canvas):
    """Grid beliefs as heat maps, one kept picture per filter."""

    def __init__(self, fonts: dict[str, pygame.font.Font]):
        super().__init__(fonts)
        self._heat_cache: dict[str, tuple[tuple, pygame.Surface, tuple[int, int]]] = {}

    def _heat(self, surf, view: View, name: str, bel: GridBelief, colour, tick: int) -> None:
        """The grid belief as a translucent heat map in the filter's colour."""
        key = (tick, view.key, id(bel.prob))
        cached = self._heat_cache.get(name)
        if cached is None or cached[0] != key:
            made = self._make_heat(view, bel, colour)
            if made is None:
                self._heat_cache.pop(name, None)
                return
            cached = (key, *made)
            self._heat_cache[name] = cached
        _, image, at = cached
        surf.blit(image, at)

    @staticmethod
    def _make_heat(view: View, bel: GridBelief, colour):
        prob = np.asarray(bel.prob, dtype=float)
        nx, ny = prob.shape
        ox, oy = bel.origin
        c = bel.cell
        vx0, vy0, vx1, vy1 = view.visible_world()
        i0, i1 = max(math.floor((vx0 - ox) / c), 0), min(math.ceil((vx1 - ox) / c), nx)
        j0, j1 = max(math.floor((vy0 - oy) / c), 0), min(math.ceil((vy1 - oy) / c), ny)
        if i1 <= i0 or j1 <= j0:
            return None
        sub = prob[i0:i1, j0:j1]
        top = float(prob.max())
        if not top > 0:
            return None
        # sqrt: faint mass stays visible. A flat belief is a light tint, a peaked one strong:
        # the peak alpha grows from 60 (uniform, max / mean = 1) towards 200.
        peak = top / max(float(prob.mean()), 1e-300)
        strength = 60.0 + 140.0 * (1.0 - math.exp(-(peak - 1.0) / 3.0))
        alpha = np.sqrt(np.clip(sub / top, 0.0, 1.0)) * strength
        # Crop to the cells that show at all: blitting and scaling cost grows with the area.
        rows = np.flatnonzero(alpha.max(axis=1) >= 1.0)
        cols = np.flatnonzero(alpha.max(axis=0) >= 1.0)
        if not len(rows) or not len(cols):
            return None
        i0, i1 = i0 + rows[0], i0 + rows[-1] + 1
        j0, j1 = j0 + cols[0], j0 + cols[-1] + 1
        alpha = alpha[rows[0]: rows[-1] + 1, cols[0]: cols[-1] + 1]
        small = pygame.Surface((i1 - i0, j1 - j0), pygame.SRCALPHA)
        small.fill((*colour, 0))
        a = pygame.surfarray.pixels_alpha(small)
        a[:] = alpha[:, ::-1].astype(np.uint8)  # screen y down: flip the y index
        del a
        corner = view.to_px(np.array([[ox + i0 * c, oy + j1 * c], [ox + i1 * c, oy + j0 * c]]))
        w = max(ipx(corner[1, 0] - corner[0, 0]), 1)
        h = max(ipx(corner[1, 1] - corner[0, 1]), 1)
        if w * h > 6_000_000:
            return None
        image = pygame.transform.scale(small, (w, h))
        return image, (ipx(corner[0, 0]), ipx(corner[0, 1]))
