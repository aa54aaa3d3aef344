"""The side panel's kept picture (app/panel_cache.py): every frame's panel has the pixels of
drawing it afresh, whatever changed (a figure, a label, the FPS, the help drawn over it), and
the picture is drawn again only when what the panel says changes."""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import numpy as np
import pygame
import pytest

from beacon_sim.app.panel_cache import KeptPanel, PanelOps, draw_line, volatile
from beacon_sim.app.window import SCRIPTED_FRAME_S, App
from beacon_sim.core.scenario import load_any_scenario
from beacon_sim.runs.live import Session


def make_app(name: str = "default", filters=("ekf", "dead_reckoning"), size=(960, 600)) -> App:
    team = load_any_scenario(name)
    sc = team.robots[0].scenario if team.solo else team
    s = Session(sc, list(filters), 5)
    s.toggle_autopilot()
    app = App(s, size, scripted=True)
    app.smooth = True
    return app


class Checked:
    """Wraps the app's panel: after each kept panel, the same panel drawn afresh (straight
    onto a copy of the screen) must have the same pixels in the panel's rectangle."""

    def __init__(self, app: App):
        self.app = app
        self.frames = self.bad = 0
        self.kept = app.hud.panel

        def panel(surf, rect, session, colours, info):
            self.kept(surf, rect, session, colours, info)
            fresh = surf.copy()
            app.hud.draw_panel(fresh, rect, session, colours, info)
            a = pygame.surfarray.array3d(surf.subsurface(rect))
            b = pygame.surfarray.array3d(fresh.subsurface(rect))
            self.frames += 1
            self.bad += int(not np.array_equal(a, b))

        app.hud.panel = panel


@pytest.mark.parametrize("name,filters", [("default", ("ekf", "dead_reckoning")),
                                          ("team_sparse", ("centralised", "ci"))])
def test_the_kept_panel_has_the_pixels_of_a_fresh_one_every_frame(name, filters):
    app = make_app(name, filters)
    try:
        check = Checked(app)
        for i in range(150):
            if i % 7 == 0:  # the FPS figure changes (drawn apart from the kept picture)
                app.frame_times.append(1.0 / (30 + i % 40))
            if i == 40:
                app.act_toggle(1)  # a label changes: "(hidden)"
            if i == 60:
                app.act_help()  # drawn over the panel ...
            if i == 63:
                app.act_help()  # ... and gone
            if i == 80:
                app.act_pause()
            if i == 100:
                app.act_pause()
            app.frame(SCRIPTED_FRAME_S)
            # what the screen shows after the frame, help aside, is the fresh panel too
            if not app.help:
                rect = app.panel_rect
                shown = pygame.surfarray.array3d(app.screen.subsurface(rect))
                fresh = app.screen.copy()
                info = {"speed": app.clock.speed, "paused": app.clock.paused, "mode": app.mode,
                        "delivered": app.pace.factor, "fps": check.last_fps(app),
                        "recording": None, "reload_errors": {}, "bound": None}
                app.hud.draw_panel(fresh, rect, app.session, app.colours, info)
                assert np.array_equal(shown, pygame.surfarray.array3d(fresh.subsurface(rect))), i
        assert check.frames == 150 and check.bad == 0
        kept = app.hud.kept_panel
        assert kept.redraws + kept.partial < 100  # kept between ticks
        assert kept.partial > 0  # a tick redraws only the figures that changed
    finally:
        app.close()


def _last_fps(app):
    from beacon_sim.app.pace import fps_of

    return fps_of(np.array(app.frame_times))


Checked.last_fps = staticmethod(_last_fps)


def test_the_panel_is_drawn_again_when_its_text_changes_and_not_otherwise():
    app = make_app()
    try:
        app.act_pause()
        for _ in range(3):
            app.frame(SCRIPTED_FRAME_S)
        kept = app.hud.kept_panel
        drawn = (kept.redraws, kept.partial, kept.blits)
        for i in range(5):  # the same panel; only the FPS changes
            app.frame_times.append(1.0 / (20 + 10 * i))
            app.frame(SCRIPTED_FRAME_S)
        assert (kept.redraws, kept.partial, kept.blits) == drawn
        app.session.status["ekf"].warning = "ekf slow: 99 ms per step"
        app.frame(SCRIPTED_FRAME_S)
        assert (kept.redraws, kept.partial) != drawn[:2]  # the new line is drawn
        check = Checked(app)
        app.frame(SCRIPTED_FRAME_S)
        assert check.frames == 1 and check.bad == 0
    finally:
        app.close()


def test_a_picture_drawn_in_part_equals_one_drawn_whole():
    """Two panels that differ in one text: the second drawn in part over the first, and
    drawn whole, give the same picture; a clip recorded in the list is kept."""
    pygame.font.init()
    font = pygame.font.Font(None, 24)
    surf = pygame.Surface((400, 300))
    rect = pygame.Rect(100, 0, 300, 300)

    def panel(text):
        def draw(target):
            target.fill((240, 240, 240), rect)
            draw_line(target, (40, 40, 40), rect.topleft, rect.bottomleft, 3)
            target.blit(font.render("title", True, (0, 0, 0)), (110, 10))
            target.blit(font.render(text, True, (200, 0, 0)), (110, 40))
            old = target.get_clip()
            target.set_clip(rect.inflate(-100, 0))
            target.blit(font.render("a long line cut at the clip", True, (0, 0, 90)), (110, 45))
            with volatile(target):
                target.blit(font.render(f"FPS {len(text)}", True, (0, 0, 0)), (110, 200))
            target.set_clip(old)
        return draw

    kept = KeptPanel()
    surf.fill((9, 9, 9))
    kept.show(surf, rect, panel("err 0.10 m"))
    kept.intact = True
    kept.show(surf, rect, panel("err 12.5 m"))
    assert kept.redraws == 1 and kept.partial == 1 and kept.blits == 1
    fresh = pygame.Surface((400, 300))
    fresh.fill((9, 9, 9))
    panel("err 12.5 m")(fresh)
    assert np.array_equal(pygame.surfarray.array3d(surf), pygame.surfarray.array3d(fresh))
    rec = PanelOps(rect)
    panel("x")(rec)
    assert [op[0] for op in rec.ops].count("clip") == 2
    assert len(rec.apart) == 2  # the FPS and the edge line over the world's last column
