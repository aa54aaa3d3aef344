"""Text and panel scale with the window: at 1024x768 (a classroom
projector) every line of the panel fits inside it, and at 1600x1000 the text is larger."""

from __future__ import annotations

import os
from dataclasses import dataclass

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import pygame
import pytest

from beacon_sim.app.hud import Hud
from beacon_sim.app.main import SCRIPTED_FRAME_S, App
from beacon_sim.core.scenario import load_scenario
from beacon_sim.runs.live import Session


def panel_lines(size, monkeypatch):
    """(app, [rect of every text the panel drew]) after 12 s of assignment_kf."""
    drawn = []
    real = Hud._blit

    def spy(self, surf, text, font, colour, at, bg=None):
        r = real(self, surf, text, font, colour, at, bg)
        drawn.append((text, r))
        return r

    monkeypatch.setattr(Hud, "_blit", spy)
    sc = load_scenario("assignment_kf")
    s = Session(sc, ["kf", "ukf", "dead_reckoning"], None)
    s.toggle_autopilot()
    app = App(s, size, scripted=True)
    app.act("bound")
    for _ in range(720):
        app.frame(SCRIPTED_FRAME_S)
    drawn.clear()
    app.draw()
    return app, drawn


@dataclass(frozen=True)
class Panel:
    """What a window of one size drew in its panel after 12 s, kept once the window closed."""

    rect: pygame.Rect
    linesize: int
    texts: list  # (text, rect) of every text drawn inside the panel


@pytest.fixture(scope="module")
def panel():
    """``panel(size)``: the Panel of a window of that size, each size drawn once a module
    (720 frames of drawing: the parametrized fit check and the growth check share them)."""
    panels: dict[tuple[int, int], Panel] = {}

    def get(size):
        if size not in panels:
            with pytest.MonkeyPatch.context() as mp:
                app, drawn = panel_lines(size, mp)
            try:
                rect = app.panel_rect.copy()
                panels[size] = Panel(rect, app.fonts["hud"].get_linesize(),
                                     [(t, r) for t, r in drawn if r.left >= rect.left])
            finally:
                app.close()
        return panels[size]

    return get


@pytest.mark.parametrize("size", [(1024, 768), (1280, 800), (1600, 1000)])
def test_every_panel_line_fits_inside_the_panel(size, panel):
    p = panel(size)
    texts = p.texts
    assert len(texts) > 15
    for text, r in texts:
        assert r.right <= p.rect.right - 4 and r.bottom <= p.rect.bottom, (size, text, r)
    # no two lines of the panel overlap
    rects = [r for _, r in texts]
    for i, a in enumerate(rects):
        for b in rects[i + 1:]:
            assert not a.colliderect(b), (size, a, b)


def test_text_and_panel_grow_with_the_window(panel):
    small, big = panel((1024, 768)), panel((1600, 1000))
    assert small.linesize < big.linesize
    assert small.rect.width < big.rect.width
    assert small.rect.width <= 0.3 * 1024
