"""Colours: the Okabe-Ito colour-blind-safe set on a light background, for a projector.

A light background keeps contrast in a lit classroom; every filter colour is from
Okabe & Ito (2008) and distinguishable with the common colour-vision deficiencies.
Yellow (poor on white) is used last. Colours are ``(r, g, b)`` tuples, 0-255.
"""

from __future__ import annotations

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

def lighten(colour: tuple[int, int, int], amount: float) -> tuple[int, int, int]:
    """Blend ``colour`` towards white by ``amount`` in [0, 1]."""
    return tuple(round(c + (255 - c) * amount) for c in colour)  # type: ignore[return-value]


__all__ = ["DASHED", "DASH_DOT", "DEAD_RECKONING", "DOTTED", "KIND_STYLES", "OKABE_ITO",
           "SHORT_DASH", "SOLID", "filter_colours", "filter_kind", "filter_styles", "lighten",
           "team_filter_styles"]
