"""Colours: the Okabe-Ito colour-blind-safe set on a light background, for a projector.

A light background keeps contrast in a lit classroom; every filter colour is from
Okabe & Ito (2008) and distinguishable with the common colour-vision deficiencies.
Yellow (poor on white) is used last. Colours are ``(r, g, b)`` tuples, 0-255.
"""

from __future__ import annotations

import functools

# The per-kind filter colours and line styles live in runs/styles.py (pygame-free), so the
# evaluation's plots use the same ones; re-exported here for the window's modules.
from beacon_sim.runs.styles import (
    DASH_DOT,
    DASHED,
    DEAD_RECKONING,
    DOTTED,
    KIND_STYLES,
    OKABE_ITO,
    SHORT_DASH,
    SOLID,
    filter_colours,
    filter_kind,
    filter_styles,
    team_filter_styles,
)

BACKGROUND = (250, 250, 247)
OUTSIDE = (228, 228, 224)  # beyond the world bounds
GRID_MINOR = (226, 226, 222)
GRID_MAJOR = (196, 196, 190)
BOUNDS = (40, 40, 40)
TEXT = (15, 15, 15)
TEXT_DIM = (90, 90, 90)
PANEL = (255, 255, 255)
PANEL_EDGE = (60, 60, 60)

ROBOT = (20, 20, 20)  # the true robot's chassis
ROBOT_MARK = (255, 255, 255)  # heading mark on the chassis
ROBOT_WHEEL = (110, 110, 110)
TRUTH_TRAIL = (20, 20, 20)
SENSOR_FILL = (232, 240, 250)
SENSOR_EDGE = (150, 175, 205)
RAY = (70, 70, 70)  # a beacon reading: solid grey
ROBOT_RAY = (150, 40, 120)  # a robot-to-robot reading: dashed, a dark reddish purple
ROBOT_RAY_DASH = (12, 7)
DRIVEN = (240, 228, 66)  # Okabe-Ito yellow: the halo under the robot the keys drive
BEACON = (40, 40, 40)
BEACON_SEEN = (0, 158, 115)  # bluish green
BEACON_SEEN_RING = (0, 110, 80)
WARN = (213, 94, 0)  # vermillion: NEES out of band, failures, kidnap banner
WARN_BG = (255, 236, 222)
BANNER_BG = (213, 94, 0)
BANNER_TEXT = (255, 255, 255)
OVERLAY_BG = (20, 20, 20)
OVERLAY_TEXT = (250, 250, 250)
OVERLAY_KEY = (240, 228, 66)  # Okabe-Ito yellow reads well on the dark overlay

#: What particles are drawn on: the floor, and the floor under the sensor disc's tint.
FLOORS = (BACKGROUND, tuple(round(b * s / 255) for b, s in zip(BACKGROUND, SENSOR_FILL, strict=True)))
#: Particles' contrast against every floor (WCAG ratio): the ones carrying the belief, and
#: the light ones (below half the mean weight), which still read on a projector.
PARTICLE_CONTRAST = 4.5
LIGHT_PARTICLE_CONTRAST = 3.0


def lighten(colour: tuple[int, int, int], amount: float) -> tuple[int, int, int]:
    """Blend ``colour`` towards white by ``amount`` in [0, 1]."""
    return tuple(round(c + (255 - c) * amount) for c in colour)  # type: ignore[return-value]


def darken(colour: tuple[int, int, int], amount: float) -> tuple[int, int, int]:
    """Blend ``colour`` towards black by ``amount`` in [0, 1]."""
    return tuple(round(c * (1.0 - amount)) for c in colour)  # type: ignore[return-value]


def luminance(colour) -> float:
    """Relative luminance (WCAG 2), 0 (black) to 1 (white), of an sRGB colour 0-255."""
    def lin(c: float) -> float:
        c /= 255.0
        return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4
    r, g, b = (lin(float(c)) for c in colour[:3])
    return 0.2126 * r + 0.7152 * g + 0.0722 * b


def contrast_ratio(a, b) -> float:
    """WCAG contrast ratio of two colours, 1 to 21."""
    la, lb = sorted((luminance(a), luminance(b)), reverse=True)
    return (la + 0.05) / (lb + 0.05)


def with_contrast(colour: tuple[int, int, int], ratio: float,
                  against=FLOORS) -> tuple[int, int, int]:
    """``colour`` darkened just enough (same hue) to reach ``ratio`` against every colour
    of ``against``; unchanged when it already does."""
    for k in range(101):
        c = darken(colour, k / 100)
        if all(contrast_ratio(c, bg) >= ratio for bg in against):
            return c
    return (0, 0, 0)


@functools.lru_cache(maxsize=64)
def particle_colours(colour: tuple[int, int, int]) -> tuple[tuple[int, int, int], tuple[int, int, int]]:
    """(heavy, light) particle colours for a filter's colour: the heavy ones at
    :data:`PARTICLE_CONTRAST`, the light ones a lighter shade at
    :data:`LIGHT_PARTICLE_CONTRAST` against the floors."""
    heavy = with_contrast(colour, PARTICLE_CONTRAST)
    light = heavy
    for k in range(1, 101):  # the palest tint of the heavy colour that still reads at 3:1
        tint = lighten(heavy, k / 100)
        if not all(contrast_ratio(tint, bg) >= LIGHT_PARTICLE_CONTRAST for bg in FLOORS):
            break
        light = tint
    return heavy, light


__all__ = ["DASHED", "DASH_DOT", "DEAD_RECKONING", "DOTTED", "KIND_STYLES", "OKABE_ITO",
           "SHORT_DASH", "SOLID", "contrast_ratio", "darken", "filter_colours", "filter_kind",
           "filter_styles", "lighten", "particle_colours", "team_filter_styles", "with_contrast"]
