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
from beacon_sim.app.window import SCRIPTED_FRAME_S, App
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


@pytest.mark.parametrize("size", [(1024, 768), (1280, 800), (1600, 1000), (1920, 1080)])
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


@pytest.mark.parametrize("size", [(1024, 768), (1920, 1080)])
def test_a_long_name_and_a_dozen_missed_beacons_fit_the_panel(size, monkeypatch):
    """A data set's run (MRCLAM: ``mrclam_Dataset6_robot1``, a dozen landmarks in range and
    missed at once): the title and the missed list stay inside the panel (they ran past
    its edge), the list wrapped, not cut."""
    import dataclasses

    from beacon_sim.app import panel

    drawn = []
    real = Hud._blit

    def spy(self, surf, text, font, colour, at, bg=None):
        r = real(self, surf, text, font, colour, at, bg)
        drawn.append((text, r))
        return r

    monkeypatch.setattr(Hud, "_blit", spy)
    missed = list(range(6, 21))
    monkeypatch.setattr(panel, "missed_ids", lambda *a, **k: set(missed))
    sc = load_scenario("default")
    sc = dataclasses.replace(sc, name="mrclam_Dataset6_robot1_with_a_longer_name_still")
    app = App(Session(sc, ["ekf", "ukf", "dead_reckoning"]), size, scripted=True)
    try:
        app.frame(SCRIPTED_FRAME_S)
        drawn.clear()
        app.draw()
        rect = app.panel_rect
        texts = [(t, r) for t, r in drawn if r.left >= rect.left]
        for text, r in texts:
            assert r.right <= rect.right - 4 and r.bottom <= rect.bottom, (size, text, r)
        said = " ".join(t for t, _ in texts)
        assert all(f"{i}," in said or said.rstrip().endswith(str(i)) or f" {i} " in f" {said} "
                   for i in missed), said
        assert any(t.startswith("mrclam_Dataset6") for t, _ in texts)
    finally:
        app.close()


@pytest.mark.parametrize("size", [(1024, 768), (1280, 800), (1920, 1080)])
def test_a_team_panel_keeps_its_status_and_help_inside_the_panel(size, monkeypatch):
    """team_sparse with four team filters fills the panel (a block per filter, three robots):
    every line still ends inside it, the FPS line and the help hint included (at 1920x1080
    the hint was drawn below the window's edge)."""
    from beacon_sim.core.scenario import load_team_scenario
    drawn = []
    real = Hud._blit

    def spy(self, surf, text, font, colour, at, bg=None):
        r = real(self, surf, text, font, colour, at, bg)
        drawn.append((text, r))
        return r

    monkeypatch.setattr(Hud, "_blit", spy)
    team = load_team_scenario("team_sparse")
    s = Session(team, list(team.default_filters), None)
    app = App(s, size, scripted=True)
    try:
        for _ in range(30):
            app.frame(SCRIPTED_FRAME_S)
        drawn.clear()
        app.draw()
        rect = app.panel_rect
        texts = [(t, r) for t, r in drawn if r.left >= rect.left]
    finally:
        app.close()
    said = [t for t, _ in texts]
    assert any(t.startswith("H: help") for t in said) and any(t.startswith("FPS") for t in said)
    for text, r in texts:
        assert r.bottom <= rect.bottom and r.right <= rect.right - 4, (size, text, r)
