"""What every layer of the world's drawing shares (``render.WorldRenderer`` stands on it):
the fonts and a cache of rendered text (``text.TextPainter``), the line width of this frame,
the world being drawn and its sensors, and the rectangles already taken on the screen (axis
labels, beacons and their labels) that later labels keep off.
"""

from __future__ import annotations

import pygame

from beacon_sim.app.text import TextPainter
from beacon_sim.core.world import World


class Canvas(TextPainter):
    """The state the world's layers share; each layer (``*_layer.py``, ``magnifier.py``) is a
    class on top of it, and ``render.WorldRenderer`` is all of them."""

    def __init__(self, fonts: dict[str, pygame.font.Font]):
        super().__init__(fonts)
        self.last_world: World | None = None  # the world of the scene being drawn (step view)
        self.last_world_sensors: tuple = ()   # its sensors (a scan's max range)
        self.lw = 4  # line width [px]; each frame's begin() sets it for the window's height
        self.axis_rects: list[pygame.Rect] = []  # the axis labels of the static layer [px]
        self.beacon_rects: list[pygame.Rect] = []  # beacons and their labels, last drawn [px]
