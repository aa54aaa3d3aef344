"""The world's view in the window: metres to pixels inside an area, with zoom and pan, and
the sizes that follow from its scale (the grid's step, the world's rectangle on the screen).

World frame: x right, y up, metres. Screen: x right, y DOWN, pixels; only this module flips y.
"""

from __future__ import annotations

import math

import numpy as np
import pygame


class View:
    """Maps world metres to window pixels inside ``area`` (x, y, w, h), with zoom and pan.

    ``scale`` is pixels per metre; ``centre`` the world point [m] shown at the area's centre.
    """

    def __init__(self, bounds, area: tuple[int, int, int, int]):
        self.bounds = tuple(float(b) for b in bounds)
        self.area = area
        self.scale = 1.0
        self.centre = np.zeros(2)
        self.fit()

    def set_area(self, area: tuple[int, int, int, int]) -> None:
        self.area = area
        self.fit()

    def fit(self) -> None:
        """Show the whole world with a margin for the axis labels."""
        xmin, ymin, xmax, ymax = self.bounds
        _, _, w, h = self.area
        pad = 44  # px for labels and air
        self.scale = max(min((w - 2 * pad) / (xmax - xmin), (h - 2 * pad) / (ymax - ymin)), 1e-3)
        self.centre = np.array([(xmin + xmax) / 2, (ymin + ymax) / 2])

    @property
    def key(self) -> tuple:
        """Changes whenever the mapping changes (for caches)."""
        return (self.area, round(self.scale, 9), float(self.centre[0]), float(self.centre[1]))

    def to_px(self, xy) -> np.ndarray:
        """World points (..., 2) [m] -> pixel coordinates (..., 2), float."""
        xy = np.asarray(xy, dtype=float)
        ax, ay, w, h = self.area
        out = np.empty_like(xy)
        out[..., 0] = ax + w / 2 + (xy[..., 0] - self.centre[0]) * self.scale
        out[..., 1] = ay + h / 2 - (xy[..., 1] - self.centre[1]) * self.scale
        return out

    def to_world(self, px) -> np.ndarray:
        """Pixel coordinates (..., 2) -> world points [m]."""
        px = np.asarray(px, dtype=float)
        ax, ay, w, h = self.area
        out = np.empty_like(px)
        out[..., 0] = self.centre[0] + (px[..., 0] - ax - w / 2) / self.scale
        out[..., 1] = self.centre[1] - (px[..., 1] - ay - h / 2) / self.scale
        return out

    def zoom(self, factor: float, at_px) -> None:
        """Zoom by ``factor`` keeping the world point under ``at_px`` in place."""
        before = self.to_world(at_px)
        self.scale = float(np.clip(self.scale * factor, 2.0, 20000.0))
        after = self.to_world(at_px)
        self.centre = self.centre + (before - after)

    def pan(self, dx_px: float, dy_px: float) -> None:
        """Move the picture by (dx, dy) pixels."""
        self.centre = self.centre + np.array([-dx_px, dy_px]) / self.scale

    def visible_world(self) -> tuple[float, float, float, float]:
        """The world rectangle (xmin, ymin, xmax, ymax) [m] the area shows."""
        ax, ay, w, h = self.area
        (x0, y1), (x1, y0) = self.to_world(np.array([[ax, ay], [ax + w, ay + h]]))
        return x0, y0, x1, y1


def ipx(v) -> int:
    """Round a pixel coordinate to the nearest integer."""
    return math.floor(float(v) + 0.5)


def nice_step(scale: float, min_px: float = 70.0) -> float:
    """Grid spacing [m] from 1-2-5 steps so that lines are at least ``min_px`` apart."""
    target = min_px / scale
    exp = math.floor(math.log10(target))
    for m in (1.0, 2.0, 5.0, 10.0):
        step = m * 10.0**exp
        if step >= target - 1e-12:
            return step
    return 10.0 ** (exp + 1)


def world_rect(view: View) -> pygame.Rect:
    """The world's bounds on the screen [px] (the room, without the margins around it)."""
    xmin, ymin, xmax, ymax = view.bounds
    b = view.to_px(np.array([[xmin, ymax], [xmax, ymin]]))
    return pygame.Rect(ipx(b[0, 0]), ipx(b[0, 1]), ipx(b[1, 0] - b[0, 0]), ipx(b[1, 1] - b[0, 1]))
