"""Words on the screen for the panel and the notes over the world: each text rendered once and
kept, blitted at a corner (on a background if asked), wrapped or cut to a width in pixels.
"""

from __future__ import annotations

import pygame

#: Lines already wrapped: (font, text, width) -> lines (the panel wraps the same legend every
#: frame).
_WRAPPED: dict[tuple, list[str]] = {}


def wrap_text(font: pygame.font.Font, text: str, width: int) -> list[str]:
    """Greedy word wrap to ``width`` pixels."""
    key = (font, text, width)
    done = _WRAPPED.get(key)
    if done is None:
        if len(_WRAPPED) > 1024:
            _WRAPPED.clear()
        done = _WRAPPED[key] = _wrap(font, text, width)
    return list(done)


def _wrap(font: pygame.font.Font, text: str, width: int) -> list[str]:
    lines: list[str] = []
    line = ""
    for word in text.split():
        trial = f"{line} {word}".strip()
        if line and font.size(trial)[0] > width:
            lines.append(line)
            line = word
        else:
            line = trial
    if line:
        lines.append(line)
    return lines


def fit_text(font: pygame.font.Font, text: str, width: int) -> str:
    """``text``, or its middle cut out (``assignment_kf_2026...1733.jsonl``) to fit ``width``
    pixels: both ends stay readable."""
    if font.size(text)[0] <= width:
        return text
    keep = len(text)
    while keep > 2:
        keep -= 1
        head, tail = text[: (keep + 1) // 2], text[len(text) - keep // 2:]
        cut = f"{head}...{tail}"
        if font.size(cut)[0] <= width:
            return cut
    return text[:1] + "..."


def short(font: pygame.font.Font, text: str, width: int) -> str:
    """``text`` cut (with a trailing '.') to fit ``width`` pixels."""
    if font.size(text)[0] <= width:
        return text
    while len(text) > 1 and font.size(text + ".")[0] > width:
        text = text[:-1]
    return text + "."


class TextPainter:
    """Rendered text kept for the next frames (most of what is written is the same every
    frame): the world's layers (``canvas.Canvas``) and the panel, the notes over the world,
    the legend and the help (``hud.Hud``) stand on it."""

    def __init__(self, fonts: dict[str, pygame.font.Font]):
        self.fonts = fonts
        self._cache: dict[tuple, pygame.Surface] = {}

    def text(self, text: str, font: str, colour) -> pygame.Surface:
        """``text`` rendered in ``fonts[font]`` and ``colour``, from the cache."""
        key = (text, font, colour)
        img = self._cache.get(key)
        if img is None:
            if len(self._cache) > 512:
                self._cache.clear()
            img = self._cache[key] = self.fonts[font].render(text, True, colour)
        return img

    def _blit(self, surf, text: str, font: str, colour, at, bg=None) -> pygame.Rect:
        """``text`` blitted with its top left at ``at`` [px] (on ``bg`` if given); its rect."""
        img = self.text(text, font, colour)
        r = img.get_rect(topleft=(int(at[0]), int(at[1])))
        if bg is not None:
            surf.fill(bg, r.inflate(8, 2))
        surf.blit(img, r)
        return r
