"""Colours: the Okabe-Ito colour-blind-safe set on a light background, for a projector.

A light background keeps contrast in a lit classroom; every filter colour is from
Okabe & Ito (2008) and distinguishable with the common colour-vision deficiencies.
Yellow (poor on white) is used last. Colours are ``(r, g, b)`` tuples, 0-255.
"""

from __future__ import annotations

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
RAY = (70, 70, 70)
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

#: Okabe-Ito, ordered for a white background (blue, vermillion, reddish purple,
#: bluish green, orange, sky blue, yellow).
OKABE_ITO = [
    (0, 114, 178),
    (213, 94, 0),
    (204, 121, 167),
    (0, 158, 115),
    (230, 159, 0),
    (86, 180, 233),
    (240, 228, 66),
]

#: Dead reckoning is the neutral baseline: a mid grey.
DEAD_RECKONING = (128, 128, 128)

#: Line dash patterns [px on, px off, ...]; None is a solid line.
SOLID = None
DASHED = (22, 11)
DOTTED = (5, 8)
DASH_DOT = (20, 7, 5, 7)
SHORT_DASH = (9, 8)

#: One colour and one line style per filter KIND, the same in every window, plot and doc,
#: so that two filters that agree (EKF and UKF usually do) stay apart: the dashed UKF is
#: drawn over the solid EKF. Kinds not listed (a student's filter) take the rest in turn.
KIND_STYLES: dict[str, tuple[tuple[int, int, int], tuple[int, ...] | None]] = {
    "kf": (OKABE_ITO[0], SOLID),  # blue
    "ekf": (OKABE_ITO[1], SOLID),  # vermillion
    "ukf": (OKABE_ITO[3], DASHED),  # bluish green
    "pf": (OKABE_ITO[2], DOTTED),  # reddish purple
    "histogram": (OKABE_ITO[4], DASH_DOT),  # orange
    "dead_reckoning": (DEAD_RECKONING, SHORT_DASH),  # grey
}
_OTHER_STYLES = [((86, 180, 233), DASH_DOT), ((0, 0, 0), DASHED), ((86, 180, 233), SOLID),
                 ((0, 0, 0), DOTTED), ((240, 228, 66), SOLID)]
_STYLE_CYCLE = [SOLID, DASHED, DOTTED, DASH_DOT, SHORT_DASH]


def filter_kind(name: str) -> str:
    """The kind of a display name: ``ekf'`` (a second EKF) -> ``ekf``."""
    return name.rstrip("'")


def filter_styles(names: list[str]) -> dict[str, tuple[tuple[int, int, int], tuple[int, ...] | None]]:
    """``(colour, dash pattern)`` per filter name: by kind, a repeated kind (``ekf'``) keeps
    the colour and takes the next line style."""
    out: dict[str, tuple[tuple[int, int, int], tuple[int, ...] | None]] = {}
    others = 0
    for name in names:
        kind = filter_kind(name)
        if kind in KIND_STYLES:
            colour, dash = KIND_STYLES[kind]
        else:
            same = next((out[n] for n in out if filter_kind(n) == kind), None)
            if same is None:
                colour, dash = _OTHER_STYLES[others % len(_OTHER_STYLES)]
                others += 1
            else:
                colour, dash = same
        repeats = len(name) - len(kind)
        if repeats:
            dash = _STYLE_CYCLE[(_STYLE_CYCLE.index(dash) + repeats) % len(_STYLE_CYCLE)]
        out[name] = (colour, dash)
    return out


def filter_colours(names: list[str]) -> dict[str, tuple[int, int, int]]:
    """One colour per filter name, by kind (``KIND_STYLES``); dead reckoning is grey."""
    return {n: c for n, (c, _) in filter_styles(names).items()}


def lighten(colour: tuple[int, int, int], amount: float) -> tuple[int, int, int]:
    """Blend ``colour`` towards white by ``amount`` in [0, 1]."""
    return tuple(round(c + (255 - c) * amount) for c in colour)  # type: ignore[return-value]
