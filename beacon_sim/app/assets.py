"""The window's shipped fonts and icon (files in assets/, see assets/README.md).

The text is set in Atkinson Hyperlegible, so it looks the same on every machine and its
characters (0/O, 1/l/I) stay distinct on a projector. ``load_fonts`` keeps the keys and the
height scaling of the earlier pygame-default fonts; ``TTF_SCALE`` converts their nominal
sizes so that digits and capitals are as tall (and lines of text as wide) as before. Line
spacing (``get_linesize``) is about a fifth larger: the TTF keeps a wider line gap.
"""

from __future__ import annotations

import pygame

from beacon_sim.core.resources import asset_path

REGULAR = "AtkinsonHyperlegible-Regular.ttf"
BOLD = "AtkinsonHyperlegible-Bold.ttf"
ICON = "icon.png"

#: Nominal sizes for pygame's default font at a window height of 800 px.
BASE_SIZES = {"title": 40, "hud": 34, "small": 28, "label": 32, "banner": 50}
#: Which file each key is set in: headings, banners and the beacon labels drawn over the map
#: bold; the panel text regular.
FONT_FILES = {"title": BOLD, "hud": REGULAR, "small": REGULAR, "label": BOLD, "banner": BOLD}
#: Atkinson Hyperlegible at size ``s * TTF_SCALE`` has the digit height and text width of
#: pygame's default font at size ``s`` (measured: digits 1.37x, capitals 1.34x taller).
TTF_SCALE = 0.73


#: The smallest text scale: a 1024x768 projector gets 0.8 of the 1280x800 sizes, smaller
#: windows no less than this.
MIN_SCALE = 0.7


def ui_scale(width_px: int, height_px: int) -> float:
    """How big text and the panel are drawn in a ``width_px`` x ``height_px`` window,
    relative to 1280x800 (1.0): the smaller of the two ratios, at least ``MIN_SCALE``."""
    return max(min(height_px / 800.0, width_px / 1280.0), MIN_SCALE)


def font_sizes(height_px: int, width_px: int | None = None) -> dict[str, int]:
    """Point size of each font for a window ``height_px`` tall: scaled with the height,
    never below the sizes for 800 px. With ``width_px``: scaled by :func:`ui_scale`, so
    text shrinks with a narrow or low window (1024x768) and grows with a large one."""
    k = max(height_px / 800.0, 1.0) if width_px is None else ui_scale(width_px, height_px)
    return {name: max(round(s * k * TTF_SCALE), 1) for name, s in BASE_SIZES.items()}


def load_fonts(height_px: int, width_px: int | None = None) -> dict[str, pygame.font.Font]:
    """The window's fonts by role (``title``, ``hud``, ``small``, ``label``, ``banner``),
    sized for a window ``height_px`` tall (and ``width_px`` wide: see :func:`font_sizes`).
    Needs ``pygame.font.init()``."""
    return {name: pygame.font.Font(str(asset_path(FONT_FILES[name])), size)
            for name, size in font_sizes(height_px, width_px).items()}


def window_icon() -> pygame.Surface:
    """The window icon (64 x 64, with alpha), for ``pygame.display.set_icon``."""
    return pygame.image.load(str(asset_path(ICON)))
