"""The magnifier hides no beacon and as little of the room as it can (the top right corner
held beacon 6 at 1024x768), and a click on it is not a kidnap to the point hidden under it."""

from __future__ import annotations

import pytest

pygame = pytest.importorskip("pygame")

from beacon_sim.app.window import App  # noqa: E402
from beacon_sim.core.scenario import load_scenario  # noqa: E402
from beacon_sim.runs.live import Session  # noqa: E402


@pytest.mark.parametrize("size", [(1024, 768), (1920, 1080)])
def test_the_magnifier_covers_no_beacon_nor_the_robot(size):
    app = App(Session(load_scenario("default"), ["ekf", "dead_reckoning"]), size, scripted=True)
    try:
        app.run(30)
        app.draw()
        mag = app.renderer.last_magnifier
        assert mag is not None
        block = mag["block"]
        assert block.collidelist(app.renderer.beacon_rects) < 0, block
        robot = app.view.to_px(app.session.true_pose[:2])
        assert not block.collidepoint(int(robot[0]), int(robot[1]))
    finally:
        app.close()


def test_a_click_on_the_magnifier_does_not_kidnap():
    app = App(Session(load_scenario("default"), ["ekf"]), (1024, 768), scripted=True)
    try:
        app.run(30)
        app.draw()
        at = app.renderer.last_magnifier["block"].center
        for kind in (pygame.MOUSEBUTTONDOWN, pygame.MOUSEBUTTONUP):
            app.handle(pygame.event.Event(kind, button=1, pos=at))
        assert app.session.pending == []  # no kidnap queued
        free = (app.view.area[0] + 5, app.view.area[1] + 5)  # elsewhere on the world: a kidnap
        for kind in (pygame.MOUSEBUTTONDOWN, pygame.MOUSEBUTTONUP):
            app.handle(pygame.event.Event(kind, button=1, pos=free))
        assert [c["kind"] for c in app.session.pending] == ["kidnap"]
    finally:
        app.close()


@pytest.mark.parametrize("size", [(1024, 768), (1920, 1080)])
def test_with_a_beacon_in_every_corner_the_magnifier_takes_a_free_edge(size):
    """A beacon under each of the four corners' places (as MRCLAM's field has them): the
    magnifier moves to the middle of an edge that hides no beacon, rather than onto one."""
    import dataclasses

    from beacon_sim.core.world import Beacon
    sc = load_scenario("default")
    corners = [Beacon(1, 0.4, 0.4), Beacon(2, 11.6, 0.4), Beacon(3, 0.4, 7.6), Beacon(4, 11.6, 7.6),
               Beacon(5, 3.5, 2.2)]  # and one near the robot (at 2.5, 2.2), so the EKF converges
    world = dataclasses.replace(sc.world, beacons=tuple(corners))
    sc = dataclasses.replace(sc, world=world)
    app = App(Session(sc, ["ekf"]), size, scripted=True)
    try:
        app.run(30)
        app.draw()
        mag = app.renderer.last_magnifier
        assert mag is not None
        block = mag["block"]
        assert block.collidelist(app.renderer.beacon_rects) < 0, (block, app.renderer.beacon_rects)
        robot = app.view.to_px(app.session.true_pose[:2])
        assert not block.collidepoint(int(robot[0]), int(robot[1]))
    finally:
        app.close()


@pytest.mark.parametrize("scenario, t", [("global_kidnap", 25.0), ("slam_bearing_only", 30.0)])
def test_where_every_place_hides_a_beacon_a_smaller_magnifier_hides_none(scenario, t):
    """At 1024x768 every corner and edge of the full-size magnifier hides a beacon here (it
    hid global_kidnap's beacon 6 and slam_bearing_only's beacon 1, an anchor in view): a
    smaller magnifier, still wide enough for its words, hides none and not the robot."""
    from beacon_sim.app.window import SCRIPTED_FRAME_S

    sc = load_scenario(scenario)
    s = Session(sc, list(sc.default_filters))
    s.toggle_autopilot()
    app = App(s, (1024, 768), scripted=True)
    try:
        while s.time < t - 1e-9:
            app.after_tick(s.tick())
        app.frame(SCRIPTED_FRAME_S)
        app.draw()
        mag = app.renderer.last_magnifier
        assert mag is not None
        block = mag["block"]
        assert block.collidelist(app.renderer.beacon_rects) < 0, (block, app.renderer.beacon_rects)
        robot = app.view.to_px(app.session.true_pose[:2])
        assert not block.collidepoint(int(robot[0]), int(robot[1]))
        assert mag["rect"].width < int(0.3 * 768)  # smaller than the full size, which hid one
        assert pygame.Rect(app.view.area).contains(block)
    finally:
        app.close()


def test_the_magnifier_keeps_off_a_lost_beliefs_label():
    """A lost belief's label ("dead_reckoning: 95 % ellipse 27 m, wider than the world")
    above the room's top right corner, where the magnifier goes first: it goes elsewhere
    (it cut the label in global_kidnap)."""
    import numpy as np

    app = App(Session(load_scenario("default"), ["ekf"]), (1024, 768), scripted=True)
    try:
        r = app.renderer
        area = pygame.Rect(app.view.area)
        label = pygame.Rect(area.right - 300, area.top + 60, 280, 24)
        r.beacon_rects, r._lost_labels = [], [label]
        pose = np.array([2.0, 2.0, 0.0])
        r.magnifier(app.screen, app.view, pose, [("ekf", pose, np.eye(3) * 1e-4)],
                    app.colours, app.dashes, 0.2)
        block = r.last_magnifier["block"]
        assert not block.colliderect(label), (block, label)
    finally:
        app.close()


@pytest.mark.parametrize("filters, size, chart", [(["kf", "ekf"], (1024, 768), False),
                                                  (["kf", "ekf", "ukf"], (1600, 1000), True)])
def test_identical_ellipses_in_the_magnifier_take_turns(filters, size, chart):
    """assignment_kf with three beacons in view: the KF's, EKF's (and UKF's) ellipses are the
    same 9 cm; in the magnifier every colour shows along the outline (the EKF's drawn over
    the KF's hid it), as on the map, and the inset is wide enough for the note that says
    so ("kf, ekf, ukf: same ellipse" was cut at its edge)."""
    import numpy as np

    from beacon_sim.app.window import SCRIPTED_FRAME_S

    sc = load_scenario("assignment_kf")
    s = Session(sc, filters)
    s.toggle_autopilot()
    app = App(s, size, scripted=True)
    try:
        if chart:  # (docs/window.md's classroom picture: the chart takes a third of the height)
            app.act("chart")
        while s.time < 52.9 - 1e-9:
            app.after_tick(s.tick())
        app.frame(SCRIPTED_FRAME_S)
        app.draw()
        mag = app.renderer.last_magnifier
        assert mag is not None and set(mag["across_px"]) == set(filters)
        rect = mag["rect"].inflate(-6, -6)
        px = pygame.surfarray.array3d(app.screen.subsurface(rect)).reshape(-1, 3).astype(int)

        def count(colour):
            return int(np.sum(np.abs(px - np.array(colour)).sum(axis=1) < 30))

        counts = {n: count(app.colours[n]) for n in filters}
        assert min(counts.values()) > 100, counts
        note = app.fonts["small"].size(f"{', '.join(filters)}: same ellipse")[0]
        assert mag["rect"].width >= note + 8
    finally:
        app.close()
