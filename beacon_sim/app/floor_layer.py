"""The floor of the world's picture: background, metric grid, walls (and the likelihood field
under them), the world's bounds and the axis labels. Drawn once per view into a picture that
every frame blits (``render.WorldRenderer.begin``).
"""

from __future__ import annotations

import math

import numpy as np
import pygame

from beacon_sim.app import map_view, palette
from beacon_sim.app.canvas import Canvas
from beacon_sim.app.view import View, ipx, nice_step


class FloorLayer(Canvas):
    """The static layer: kept while the view, the world's grid and ``show_field`` stay."""

    def __init__(self, fonts: dict[str, pygame.font.Font]):
        super().__init__(fonts)
        self._static: tuple[tuple, pygame.Surface] | None = None
        self.show_field = False  # the likelihood field under the walls (ShowOptions.field)

    def _static_layer(self, view: View, world_rect: pygame.Rect) -> pygame.Surface:
        """Background, metric grid, bounds and axis labels: drawn once per view, then blitted."""
        grid = getattr(self.last_world, "grid", None)
        key = (view.key, id(grid), self.show_field)
        if self._static is not None and self._static[0] == key:
            return self._static[1]
        area = pygame.Rect(view.area)
        layer = pygame.Surface(area.size)
        # Draw in window coordinates on a surface offset by the area's corner.
        full = pygame.Surface((area.right, area.bottom))
        full.fill(palette.OUTSIDE)
        full.fill(palette.BACKGROUND, world_rect)
        self._grid(full, view, world_rect)
        if self.show_field:
            map_view.draw_field(full, view, grid)  # the likelihood field, under the walls
        map_view.draw_map(full, view, grid)      # walls (the occupancy grid)
        pygame.draw.rect(full, palette.BOUNDS, world_rect.inflate(4, 4), 3)
        self._axis_labels(full, view, world_rect)
        layer.blit(full, (0, 0), area)
        self._static = (key, layer)
        return layer

    # --- pieces ---------------------------------------------------------------------------
    def _grid(self, surf, view: View, world_rect: pygame.Rect) -> None:
        step = nice_step(view.scale)
        x0, y0, x1, y1 = view.visible_world()
        xmin, ymin, xmax, ymax = view.bounds
        x0, x1 = max(x0, xmin), min(x1, xmax)
        y0, y1 = max(y0, ymin), min(y1, ymax)
        minor = step / 5 if step / 5 * view.scale >= 14 else None
        for spacing, colour, width in ((minor, palette.GRID_MINOR, 1), (step, palette.GRID_MAJOR, 2)):
            if spacing is None:
                continue
            for x in np.arange(math.ceil(x0 / spacing) * spacing, x1 + 1e-9, spacing):
                px = ipx(view.to_px(np.array([x, 0.0]))[0])
                pygame.draw.line(surf, colour, (px, world_rect.top), (px, world_rect.bottom - 1), width)
            for y in np.arange(math.ceil(y0 / spacing) * spacing, y1 + 1e-9, spacing):
                py = ipx(view.to_px(np.array([0.0, y]))[1])
                pygame.draw.line(surf, colour, (world_rect.left, py), (world_rect.right - 1, py), width)

    def _axis_labels(self, surf, view: View, world_rect: pygame.Rect) -> None:
        step = nice_step(view.scale)
        x0, y0, x1, y1 = view.visible_world()
        xmin, ymin, xmax, ymax = view.bounds
        area = pygame.Rect(view.area)
        fmt = (lambda v: f"{v:g}") if step >= 1 else (lambda v: f"{v:.1f}")
        ylab = min(max(world_rect.bottom + 6, area.top + 2), area.bottom - 24)
        self.axis_rects = []  # where the labels are (window px): beacon labels keep off them
        for x in np.arange(math.ceil(max(x0, xmin) / step) * step, min(x1, xmax) + 1e-9, step):
            px = view.to_px(np.array([x, 0.0]))[0]
            t = self.text(fmt(x + 0.0), "small", palette.TEXT_DIM)
            self.axis_rects.append(surf.blit(t, (int(px - t.get_width() / 2), ylab)))
        xlab = max(min(world_rect.left - 6, area.right - 40), area.left + 2)
        for y in np.arange(math.ceil(max(y0, ymin) / step) * step, min(y1, ymax) + 1e-9, step):
            py = view.to_px(np.array([0.0, y]))[1]
            t = self.text(fmt(y + 0.0), "small", palette.TEXT_DIM)
            self.axis_rects.append(
                surf.blit(t, (max(xlab - t.get_width(), area.left + 2), int(py - t.get_height() / 2))))
        unit = self.text(f"grid {step:g} m", "small", palette.TEXT_DIM)
        box = unit.get_rect(topleft=(area.left + 8, area.top + 6))
        surf.fill(palette.OUTSIDE, box.inflate(8, 4))
        surf.blit(unit, box)
