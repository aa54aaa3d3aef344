"""Text and panel scale with the window (issue 12, item 6): at 1024x768 (a classroom
projector) every line of the panel fits inside it, and at 1600x1000 the text is larger."""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

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


@pytest.mark.parametrize("size", [(1024, 768), (1280, 800), (1600, 1000)])
def test_every_panel_line_fits_inside_the_panel(size, monkeypatch):
    app, drawn = panel_lines(size, monkeypatch)
    try:
        panel = app.panel_rect
        texts = [(t, r) for t, r in drawn if r.left >= panel.left]
        assert len(texts) > 15
        for text, r in texts:
            assert r.right <= panel.right - 4 and r.bottom <= panel.bottom, (size, text, r)
        # no two lines of the panel overlap
        rects = [r for _, r in texts]
        for i, a in enumerate(rects):
            for b in rects[i + 1:]:
                assert not a.colliderect(b), (size, a, b)
    finally:
        app.close()


def test_text_and_panel_grow_with_the_window(monkeypatch):
    small, _ = panel_lines((1024, 768), monkeypatch)
    big, _ = panel_lines((1600, 1000), monkeypatch)
    try:
        assert small.fonts["hud"].get_linesize() < big.fonts["hud"].get_linesize()
        assert small.panel_rect.width < big.panel_rect.width
        assert small.panel_rect.width <= 0.3 * 1024
    finally:
        small.close()
        big.close()
