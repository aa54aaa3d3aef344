"""A team's legend under the world: what the lines in the world mean (beacon and robot
readings, the true and the driven robot) and each team filter's line style, with a sample of
each, in rows that fit the width.
"""

from __future__ import annotations

import pygame

from beacon_sim.app import palette
from beacon_sim.app.estimate_layer import ELLIPSE_LEVEL
from beacon_sim.app.strokes import polyline
from beacon_sim.app.text import TextPainter

#: The world legend's entries that are not filters (a team's legend strip).
LEGEND_MARKS = ("ray", "robot_ray", "robot", "driven")


class TeamLegend(TextPainter):
    """The legend strip; its picture is kept until what it shows changes."""

    def __init__(self, fonts: dict[str, pygame.font.Font]):
        super().__init__(fonts)
        self._legend: tuple[tuple, pygame.Surface, pygame.Rect] | None = None  # world_legend's picture

    def legend_rows(self, width: int, names: list[str]) -> list[list[tuple[str, str]]]:
        """The legend's entries (text, what) in rows that fit ``width`` [px]: the readings
        and robots, then one entry per team filter ``names``."""
        f = self.fonts["small"]
        sample = 3 * f.get_linesize()
        items = [("beacon reading", "ray"), ("robot reading", "robot_ray"),
                 ("true robot", "robot"), ("driven (Tab)", "driven")]
        items += [(f"{name}: {ELLIPSE_LEVEL:.0%} ellipse", name) for name in names]
        room = width - 40
        rows: list[list[tuple[str, str]]] = [[]]
        used = 0
        for text, what in items:  # fill rows left to right; the filters start a new row
            wide = sample + 12 + f.size(text)[0] + 24
            if rows[-1] and (used + wide > room or (what not in LEGEND_MARKS and used
                                                    and rows[-1][-1][1] in LEGEND_MARKS)):
                rows.append([])
                used = 0
            rows[-1].append((text, what))
            used += wide
        return rows

    def legend_height(self, width: int, names: list[str]) -> int:
        """The height [px] the legend box takes under the world, margins included."""
        return len(self.legend_rows(width, names)) * (self.fonts["small"].get_linesize() + 8) + 26

    def world_legend(self, surf, area: pygame.Rect, session, colours, dashes,
                     lw: int) -> pygame.Rect:
        """What the lines in the world mean, with a sample of each, in a box at the top left
        of ``area`` (the strip under the world view): the readings, the robots, each team
        filter's style. Drawn once into a picture kept until what it shows changes (the
        filters shown, their styles, the size), then blitted: the same pixels every frame."""
        names = [n for n in session.names if session.visible[n]]
        key = (area.size, lw, tuple((n, colours[n], tuple(dashes.get(n) or ())) for n in names))
        if self._legend is None or self._legend[0] != key:
            pic = pygame.Surface(area.size, 0, surf)
            box = self._draw_world_legend(pic, pic.get_rect(), names, colours, dashes, lw)
            self._legend = (key, pic, box)
        _, pic, box = self._legend
        surf.blit(pic, area)
        return box.move(area.topleft)

    def _draw_world_legend(self, surf, area: pygame.Rect, names: list[str], colours, dashes,
                           lw: int) -> pygame.Rect:
        """:meth:`world_legend`'s drawing, of the filters ``names``, onto ``surf``."""
        f = self.fonts["small"]
        sl = f.get_linesize()
        sample = 3 * sl
        rows = self.legend_rows(area.width, names)
        widths = [sum(sample + 12 + f.size(t)[0] + 24 for t, _ in row) for row in rows]
        box = pygame.Rect(area.left + 8, area.top + 4, min(max(widths) + 12, area.width - 16),
                          len(rows) * (sl + 8) + 10)
        surf.fill(palette.OUTSIDE, area)  # the strip under the world, as around the world
        old_clip = surf.get_clip()
        surf.set_clip(area)
        shade = pygame.Surface(box.size, pygame.SRCALPHA)
        shade.fill((*palette.PANEL, 235))
        surf.blit(shade, box)
        pygame.draw.rect(surf, palette.PANEL_EDGE, box, 2)
        y = box.top + 8
        for row in rows:
            x = box.left + 10
            mid = y + sl // 2
            for text, what in row:
                a, b = (x, mid), (x + sample, mid)
                if what == "ray":
                    pygame.draw.line(surf, palette.RAY, a, b, 2)
                elif what == "robot_ray":
                    polyline(surf, palette.ROBOT_RAY, [a, (b[0] - 7, mid)], max(lw - 1, 3),
                             palette.ROBOT_RAY_DASH)
                    pygame.draw.circle(surf, palette.ROBOT_RAY, (b[0] - 7, mid), 7, 3)
                elif what == "robot":
                    r = pygame.Rect(0, 0, sl - 8, sl - 10)
                    r.center = (x + sample // 2, mid)
                    pygame.draw.rect(surf, palette.ROBOT, r, max(lw - 1, 2))
                    pygame.draw.circle(surf, palette.ROBOT, r.center, sl // 2 + 2, 2)
                elif what == "driven":
                    pygame.draw.circle(surf, palette.DRIVEN, (x + sample // 2, mid), sl // 2 + 2)
                    pygame.draw.circle(surf, palette.TEXT, (x + sample // 2, mid), sl // 2 + 2, 2)
                else:
                    polyline(surf, colours[what], [a, b], lw, dashes.get(what))
                x += sample + 12
                r = self._blit(surf, text, "small", palette.TEXT, (x, y))
                x = r.right + 24
            y += sl + 8
        surf.set_clip(old_clip)
        return box
