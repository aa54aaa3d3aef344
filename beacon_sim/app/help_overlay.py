"""The help overlay: every binding of the window's mode (``controls``), grouped, in one or two
columns sized to fit the window, in the largest font that fits.
"""

from __future__ import annotations

import pygame

from beacon_sim.app import controls, palette
from beacon_sim.app.text import TextPainter, wrap_text


class HelpOverlay(TextPainter):
    """The help over the window; ``help_drawn`` holds the (keys, description) pairs it drew."""

    mode: str  # which binding table (controls.TABLES) the help shows

    def __init__(self, fonts: dict[str, pygame.font.Font]):
        super().__init__(fonts)
        self.help_drawn: list[tuple[str, str]] = []

    def help(self, surf) -> None:
        """Every binding of the mode's table (``controls.bindings``), grouped, over a dark
        translucent box, in one or two columns sized to their text: the panel's font if
        that fits the window, else the small one, descriptions wrapped if need be (nothing
        overlaps or is cut at 1024x768)."""
        W, H = surf.get_size()
        f = self.fonts
        lines = controls.help_lines(self.mode)
        groups: list[tuple[str, list[tuple[str, str]]]] = []
        for group, keys, desc in lines:
            if not groups or groups[-1][0] != group:
                groups.append((group, []))
            groups[-1][1].append((keys, desc))
        layout = self._help_layout(groups, W, H)
        font, ncol, key_w, desc_w, wrapped = layout
        lh = f[font].get_linesize()
        rows = [(g, [(k, wrapped[(k, d)], d) for k, d in rs]) for g, rs in groups]
        heights = [1.4 + sum(len(w) for _, w, _ in rs) for _, rs in rows]
        cols, tallest = split_columns(heights, ncol)
        col_w = key_w + desc_w + 30
        title_h = f["title"].get_linesize() + 22
        box = pygame.Rect(0, 0, col_w * ncol + 40, min(int(tallest * lh + title_h + 20), H - 10))
        box.center = (W // 2, H // 2)
        shade = pygame.Surface(box.size, pygame.SRCALPHA)
        shade.fill((*palette.OVERLAY_BG, 235))
        surf.blit(shade, box)
        pygame.draw.rect(surf, palette.OVERLAY_KEY, box, 3, border_radius=6)
        self._blit(surf, "Keys and mouse  (H or F1 closes)", "title", palette.OVERLAY_TEXT,
                   (box.left + 20, box.top + 12))
        self.help_drawn = []
        self.help_rects: list[pygame.Rect] = []  # every text drawn (tests: no overlap, inside)
        y0 = box.top + title_h
        y, col = y0, 0
        for (group, rs), c in zip(rows, cols, strict=True):
            if c != col:
                col, y = c, y0
            x = box.left + 20 + col * col_w
            self.help_rects.append(self._blit(surf, group, "small", palette.OVERLAY_KEY, (x, y)))
            y += max(int(lh * 1.1), f["small"].get_linesize() + 1)
            for keys, parts, desc in rs:
                self.help_rects.append(self._blit(surf, keys, font, palette.OVERLAY_KEY, (x, y)))
                for part in parts:
                    self.help_rects.append(self._blit(surf, part, font, palette.OVERLAY_TEXT,
                                                      (x + key_w, y)))
                    y += lh
                self.help_drawn.append((keys, desc))
            y += int(lh * 0.3)
        self.help_box = box

    def _help_layout(self, groups, W: int, H: int):
        """(font, columns, key column width, description width, {(keys, desc): lines}) for
        the help overlay: the largest font whose one or two columns fit ``W`` x ``H``."""
        f = self.fonts
        pairs = [kd for _, rs in groups for kd in rs]
        for font in ("hud", "small"):
            lh = f[font].get_linesize()
            key_w = max(f[font].size(k)[0] for k, _ in pairs) + 24
            title_h = f["title"].get_linesize() + 22
            for ncol in (1, 2):
                room = (W - 60) // ncol - 30 - key_w  # px for a description
                if room < 120:
                    continue
                wrapped = {(k, d): wrap_text(f[font], d, room) or [""] for k, d in pairs}
                desc_w = max(f[font].size(p)[0] for w in wrapped.values() for p in w)
                heights = [1.4 + sum(len(wrapped[kd]) for kd in rs) for _, rs in groups]
                _, tallest = split_columns(heights, ncol)
                if tallest * lh + title_h + 20 <= H - 10:
                    if font == "hud" and any(len(w) > 1 for w in wrapped.values()):
                        continue  # rather the small font on one line than the large one wrapped
                    return font, ncol, key_w, desc_w, wrapped
        font = "small"
        key_w = max(f[font].size(k)[0] for k, _ in pairs) + 24
        room = max((W - 60) // 2 - 30 - key_w, 80)
        wrapped = {(k, d): wrap_text(f[font], d, room) or [""] for k, d in pairs}
        desc_w = max(f[font].size(p)[0] for w in wrapped.values() for p in w)
        return font, 2, key_w, desc_w, wrapped


def split_columns(heights: list[float], ncol: int) -> tuple[list[int], float]:
    """Groups of ``heights`` rows, in order, into ``ncol`` (1 or 2) columns without splitting
    a group: (each group's column, the taller column's rows). Two columns: the split that
    makes the taller one shortest."""
    if ncol == 1 or len(heights) < 2:
        return [0] * len(heights), float(sum(heights))
    best = min(range(1, len(heights)),
               key=lambda k: max(sum(heights[:k]), sum(heights[k:])))
    return ([0] * best + [1] * (len(heights) - best),
            float(max(sum(heights[:best]), sum(heights[best:]))))
