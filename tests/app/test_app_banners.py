"""Banners cover no robot (at the top of the world when the robot is not under it, else at
its bottom) and an event's banner is cleared by a seek in a replay."""

from __future__ import annotations

import pytest

pygame = pytest.importorskip("pygame")

from replay_app_helpers import (  # noqa: E402
    make,
    run_until,
)

from beacon_sim.app.window import App  # noqa: E402
from beacon_sim.core.scenario import load_scenario  # noqa: E402
from beacon_sim.runs.live import Session  # noqa: E402


@pytest.mark.parametrize("size", [(1024, 768), (1920, 1080)])
def test_a_banner_does_not_sit_on_the_robot(size):
    app = App(Session(load_scenario("default"), ["ekf"]), size, scripted=True)
    try:
        top_middle = app.view.to_world((app.view.area[0] + app.view.area[2] / 2, app.view.area[1] + 40))
        for y in (float(top_middle[1]), 1.0):  # under the banner's usual place, and away from it
            app.session.command({"kind": "kidnap", "pose": [float(top_middle[0]), y, 0.0]})
            app.run(app.frames + 6)
            app.flash("KIDNAPPED: a long message across the top of the world")
            app.draw()
            assert not app.hud.banner_box.colliderect(app.robot_box()), (y, app.hud.banner_box)
            assert pygame.Rect(app.view.area).contains(app.hud.banner_box)
    finally:
        app.close()


def test_a_seek_clears_the_kidnap_banner(recorded):
    path, _ = recorded
    app = make(path)
    try:
        run_until(app, 152)  # the recorded kidnap at tick 150
        assert app.now < app.banner_until and "KIDNAPPED" in app.banner_text
        app.seek(20)
        assert not app.now < app.banner_until
    finally:
        app.close()


@pytest.mark.parametrize("size", [(1024, 768), (1920, 1080)])
def test_a_banner_moved_off_the_robot_hides_no_beacon(size):
    """The robot against the top wall under the banner's usual place, beacon 5 just below
    it: the banner goes to the bottom of the world's area (at 1920x1080 it went just under
    the robot, over beacon 5, the one the robot was reading)."""
    app = App(Session(load_scenario("default"), ["ekf"]), size, scripted=True)
    try:
        app.session.command({"kind": "kidnap", "pose": [6.0, 7.6, 1.57]})
        app.run(6)
        app.flash("BUMPER: the robot hit the wall and stopped (v = 0)")
        app.draw()
        box = app.hud.banner_box
        assert not box.colliderect(app.robot_box())
        assert box.collidelist(app.renderer.beacon_rects) < 0, (box, app.renderer.beacon_rects)
        assert pygame.Rect(app.view.area).contains(box)
    finally:
        app.close()


def test_a_kidnap_banner_says_its_kind_without_brackets_in_brackets():
    app = App(Session(load_scenario("default"), ["ekf"]), (1024, 768), scripted=True)
    try:
        app.session.command({"kind": "kidnap", "pose": [3.0, 3.0, 0.0]})
        app.run(app.frames + 6)
        assert app.banner_text == "KIDNAPPED: to a pose (user)"
    finally:
        app.close()


@pytest.mark.parametrize("size", [(1024, 768), (1920, 1080)])
def test_a_banner_covers_neither_the_magnifier_nor_the_step_views_legend(size):
    """The magnifier (shown at the start of default) and the step view's legend with the
    bound are drawn over the world; a long banner keeps off them, and off the robot."""
    app = App(Session(load_scenario("default"), ["ekf", "dead_reckoning"]), size, scripted=True)
    try:
        app.run(30)
        app.act("bound")
        app.act("pause")
        app.act("step_view")
        app.flash("KIDNAPPED: a long message across the top of the world, wider than most")
        app.draw()
        mag = app.renderer.last_magnifier
        assert mag is not None
        banner = app.hud.banner_box
        assert not banner.colliderect(mag["block"]), (banner, mag["block"])
        assert not banner.colliderect(app.hud.step_box), (banner, app.hud.step_box)
        assert not banner.colliderect(app.robot_box())
        assert pygame.Rect(app.view.area).contains(banner)
    finally:
        app.close()


def test_a_banner_takes_the_bottom_when_the_top_is_kept_clear():
    """The banner's own choice: the top of the area held by a note, the robot elsewhere."""
    app = App(Session(load_scenario("default"), ["ekf"]), (1024, 768), scripted=True)
    try:
        area = pygame.Rect(app.view.area)
        note = pygame.Rect(area.left, area.top, area.width, 120)
        surf = pygame.Surface(app.screen.get_size())
        robot = pygame.Rect(area.left + 10, area.centery - 20, 40, 40)
        app.hud.banner(surf, area, "BUMPER: the robot hit the wall", robot, keep_clear=[note])
        assert not app.hud.banner_box.colliderect(note)
        assert app.hud.banner_box.bottom > area.centery
        app.hud.banner(surf, area, "BUMPER: the robot hit the wall", robot)
        assert app.hud.banner_box.top < area.top + 30  # with nothing to keep clear: the top
    finally:
        app.close()
