"""One colour and one line style per filter KIND, the same in the window, the evaluation's
plots and the docs (no pygame, no matplotlib here: ``app/palette.py`` and
``evaluation/plots.py`` both read this table).

Colours are Okabe & Ito (2008), colour-blind safe, as ``(r, g, b)`` 0-255; dead reckoning,
the baseline, is grey. Line styles are dash patterns (length on, length off, ...) in
screen pixels; None is solid. Two filters that usually agree (EKF and UKF) differ in both,
so the dashed UKF drawn over the solid EKF leaves both visible.
"""

from __future__ import annotations

from collections.abc import Mapping

from beacon_sim.filters.registry import FilterRecord, RecordTable

RGB = tuple[int, int, int]
Dash = tuple[int, ...] | None

#: Okabe-Ito, ordered for a white background (blue, vermillion, reddish purple,
#: bluish green, orange, sky blue, yellow).
OKABE_ITO: list[RGB] = [
    (0, 114, 178),
    (213, 94, 0),
    (204, 121, 167),
    (0, 158, 115),
    (230, 159, 0),
    (86, 180, 233),
    (240, 228, 66),
]

#: Dead reckoning is the neutral baseline: a mid grey.
DEAD_RECKONING: RGB = (128, 128, 128)

#: Line dash patterns [px on, px off, ...]; None is a solid line.
SOLID: Dash = None
DASHED: Dash = (22, 11)
DOTTED: Dash = (5, 8)
DASH_DOT: Dash = (20, 7, 5, 7)
SHORT_DASH: Dash = (9, 8)

#: Colours by the names the filters' records use (filters/registry.py).
COLOURS: dict[str, RGB] = {
    "blue": OKABE_ITO[0], "vermillion": OKABE_ITO[1], "reddish purple": OKABE_ITO[2],
    "bluish green": OKABE_ITO[3], "orange": OKABE_ITO[4], "sky blue": OKABE_ITO[5],
    "yellow": OKABE_ITO[6], "grey": DEAD_RECKONING, "black": (0, 0, 0),
}
#: Line styles by the names the filters' records use.
DASHES: dict[str, Dash] = {
    "solid": SOLID, "dashed": DASHED, "dotted": DOTTED, "dash-dot": DASH_DOT, "short dash": SHORT_DASH,
}


def record_style(record: FilterRecord) -> tuple[RGB, Dash]:
    """``(colour, dash pattern)`` of a built-in filter's record."""
    colour, dash = record.style
    return COLOURS[colour], DASHES[dash]


#: Colour and line style by filter kind, from the records (kf blue and solid, ekf
#: vermillion and solid, ukf bluish green and dashed, pf reddish purple and dotted,
#: histogram orange and dash-dot, dead reckoning grey and short dashes). Kinds not listed
#: (a student's filter) take ``OTHER_STYLES`` in turn.
KIND_STYLES: Mapping[str, tuple[RGB, Dash]] = RecordTable(record_style)
OTHER_STYLES: list[tuple[RGB, Dash]] = [
    (OKABE_ITO[5], DASH_DOT), ((0, 0, 0), DASHED), (OKABE_ITO[5], SOLID), ((0, 0, 0), DOTTED),
    (OKABE_ITO[6], SOLID)]
STYLE_CYCLE: list[Dash] = [SOLID, DASHED, DOTTED, DASH_DOT, SHORT_DASH]

#: Team filters (``filters/team.py``) by name, from their records: the baseline
#: that ignores the teammates is grey like dead reckoning; the joint EKF blue and solid; the
#: pairwise decentralised EKF orange, dash-dot; covariance intersection bluish green and
#: dashed; naive fusion, the overconfident counter-example, vermillion and dotted. Others (a
#: student's team filter) take ``OTHER_STYLES`` in turn.
TEAM_STYLES: Mapping[str, tuple[RGB, Dash]] = RecordTable(record_style, team=True)

#: The best achievable covariance (the PCRB) wherever it is drawn: black, dotted.
BOUND_STYLE: tuple[RGB, Dash] = ((0, 0, 0), (3, 6))


def filter_kind(name: str) -> str:
    """The kind of a display name: ``ekf'`` (a second EKF) -> ``ekf``."""
    return name.rstrip("'")


#: The colours a filter takes, in order, when its kind's colour is already another kind's
#: among the filters shown together.
SPARE_COLOURS: list[RGB] = [*OKABE_ITO, (0, 0, 0), DEAD_RECKONING]


def filter_styles(names: list[str]) -> dict[str, tuple[RGB, Dash]]:
    """``(colour, dash pattern)`` per filter name: by kind; a repeated kind (``ekf'``) keeps
    the colour and takes the next line style. Different kinds shown together never share a
    colour: a kind whose colour an earlier kind took (mcl and ekf_slam are both sky blue; a
    named filter ``delayed=ekf_slam`` takes the first of ``OTHER_STYLES``) takes the first
    of ``SPARE_COLOURS`` no other kind of ``names`` has."""
    out: dict[str, tuple[RGB, Dash]] = {}
    kind_colour: dict[str, RGB] = {}
    wanted = {KIND_STYLES[filter_kind(n)][0] for n in names if filter_kind(n) in KIND_STYLES}
    others = 0
    for name in names:
        kind = filter_kind(name)
        if kind in kind_colour:  # a repeated kind: its colour, the next line style
            colour, dash = kind_colour[kind], next(out[n] for n in out if filter_kind(n) == kind)[1]
        else:
            if kind in KIND_STYLES:
                colour, dash = KIND_STYLES[kind]
            else:
                colour, dash = OTHER_STYLES[others % len(OTHER_STYLES)]
                others += 1
            taken = set(kind_colour.values())
            if colour in taken:
                spare = [c for c in SPARE_COLOURS if c not in taken and c not in wanted]
                spare = spare or [c for c in SPARE_COLOURS if c not in taken]
                colour = spare[0] if spare else colour
            kind_colour[kind] = colour
        repeats = len(name) - len(kind)
        if repeats:
            dash = STYLE_CYCLE[(STYLE_CYCLE.index(dash) + repeats) % len(STYLE_CYCLE)]
        out[name] = (colour, dash)
    return out


def team_filter_styles(names: list[str]) -> dict[str, tuple[RGB, Dash]]:
    """``(colour, dash pattern)`` per team filter name (``TEAM_STYLES``; ``independent:F``
    takes the single-robot style of F's kind, so ``independent:pf`` looks like the particle
    filter; any other name takes the next of ``OTHER_STYLES``). Two names never share a
    colour and a line style: a later one takes the next line style."""
    out: dict[str, tuple[RGB, Dash]] = {}
    others = 0
    for name in names:
        member = name.split(":", 1)[1] if name.startswith("independent:") else None
        if name in TEAM_STYLES:
            colour, dash = TEAM_STYLES[name]
        elif member is not None and member in KIND_STYLES:
            colour, dash = KIND_STYLES[member]
        else:
            colour, dash = OTHER_STYLES[others % len(OTHER_STYLES)]
            others += 1
        for _ in range(len(STYLE_CYCLE)):
            if (colour, dash) not in out.values():
                break
            dash = STYLE_CYCLE[(STYLE_CYCLE.index(dash) + 1) % len(STYLE_CYCLE)]
        out[name] = (colour, dash)
    return out


def filter_colours(names: list[str]) -> dict[str, RGB]:
    """One colour per filter name, by kind (``KIND_STYLES``); dead reckoning is grey."""
    return {n: c for n, (c, _) in filter_styles(names).items()}


def hex_colour(colour: RGB) -> str:
    """``(r, g, b)`` 0-255 -> ``"#rrggbb"`` (for matplotlib, HTML, docs)."""
    return "#{:02x}{:02x}{:02x}".format(*colour)


def plot_linestyle(dash: Dash, scale: float = 0.25) -> str | tuple[float, tuple[float, ...]]:
    """A dash pattern as a matplotlib ``linestyle``: ``"-"`` for solid, else
    ``(0, (on, off, ...))`` in points (window pixels times ``scale``: a plot's lines are
    thinner than the window's, so its dashes are shorter)."""
    if dash is None:
        return "-"
    return (0.0, tuple(max(d * scale, 0.5) for d in dash))
