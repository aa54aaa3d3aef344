"""What the world shows where lines would lie or hide (SDL dummy driver): a belief wider
than the world as a marker and a label, not lines across the world; ellipses that lie on
one another in stripes of each colour with a note; the sensor's disc cut by the walls; a
scan's readings beyond a wall drawn to the wall, apart from the hits."""

from __future__ import annotations

import math
import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import numpy as np
import pygame
import pytest

from beacon_sim.app import map_view, shapes
from beacon_sim.app.window import SCRIPTED_FRAME_S, App
from beacon_sim.core.raycast import cast_rays
from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.types import Measurement
from beacon_sim.runs.live import Session


@pytest.fixture
def app():
    a = App(Session(load_scenario("default"), ["ekf", "ukf", "pf"]), (1280, 800), scripted=True)
    a.frame(SCRIPTED_FRAME_S)
    yield a
    a.close()


def colour_count(surf, colour) -> int:
    px = pygame.surfarray.array3d(surf)
    return int(np.all(px == np.array(colour[:3]), axis=2).sum())


def blank(app) -> pygame.Surface:
    surf = pygame.Surface(app.screen.get_size(), 0, app.screen)
    surf.fill((255, 255, 255))
    surf.set_clip(pygame.Rect(app.view.area))
    return surf


def test_a_belief_wider_than_the_world_is_a_marker_and_a_label_not_lines(app):
    r, view = app.renderer, app.view
    surf = blank(app)
    wide = np.diag([400.0, 0.05, 0.1])  # 98 m across along x: a line across everything
    r.estimates(surf, view, [("pf", np.array([6.0, 3.0, 0.0]), wide)], app.colours, {}, 0.2, True)
    colour = app.colours["pf"]
    assert [b for b in r._lost_labels]  # the label was placed
    # nothing of pf's colour far from the estimate, but in the label's frame
    px = pygame.surfarray.array3d(surf)
    ys, xs = np.nonzero(np.all(px.transpose(1, 0, 2) == np.array(colour[:3]), axis=2))
    c = view.to_px(np.array([6.0, 3.0]))
    label = r._lost_labels[0]
    far = np.hypot(xs - c[0], ys - c[1]) > 60
    in_label = (xs >= label.left) & (xs < label.right) & (ys >= label.top) & (ys < label.bottom)
    assert far.any() and not (far & ~in_label).any()
    # the same belief 1 m across: an ellipse, no label
    surf = blank(app)
    r.estimates(surf, view, [("pf", np.array([6.0, 3.0, 0.0]), np.diag([0.02, 0.02, 0.1]))],
                app.colours, {}, 0.2, True)
    assert r._lost_labels == []


def test_ellipses_on_one_another_take_turns_in_stripes_and_say_so(app):
    r, view = app.renderer, app.view
    cov = np.diag([0.5, 0.2, 0.01])
    mean = np.array([3.0, 4.0, 0.3])
    counts = {}
    for order in (("ekf", "ukf"), ("ukf", "ekf")):
        surf = blank(app)
        r.estimates(surf, view, [(k, mean, cov.copy()) for k in order], app.colours,
                    dict(app.dashes), 0.2, True, wedges=False)
        counts[order] = {k: colour_count(surf, app.colours[k]) for k in order}
    for got in counts.values():
        a, b = got.values()
        assert min(a, b) > 0.7 * max(a, b), got  # each colour about half the outline
    # apart, each is drawn whole in its own style
    surf = blank(app)
    r.estimates(surf, view, [("ekf", mean, cov), ("ukf", mean + np.array([3.0, 0.0, 0.0]), cov)], app.colours,
                dict(app.dashes), 0.2, True, wedges=False)
    assert colour_count(surf, app.colours["ekf"]) > 2 * counts[("ekf", "ukf")]["ekf"] * 0.8


def test_the_sensor_disc_stops_at_the_walls():
    sc = load_scenario("two_rooms")
    grid = sc.world.grid
    spec = next(s for s in sc.sensors if math.isfinite(s.max_range))
    pose = np.array([6.2, 1.1, 0.0])  # in the right-hand room, the door to its left
    out = shapes.sensor_outline(pose, spec.fov, spec.max_range, grid)
    d = np.hypot(*(out - pose[:2]).T)
    assert d.max() <= spec.max_range + 1e-9
    assert (d < spec.max_range - 0.5).mean() > 0.2  # walls cut a good part of it
    # no point of the outline lies beyond a wall: a ray to each stops no nearer
    ang = np.arctan2(*(out - pose[:2]).T[::-1])
    assert np.all(d <= cast_rays(grid, pose[:2], ang, spec.max_range) + 1e-6)
    open_disc = shapes.sensor_outline(pose, spec.fov, spec.max_range, None)
    assert np.allclose(np.hypot(*(open_disc - pose[:2]).T), spec.max_range)


def test_a_scan_reading_beyond_the_wall_is_drawn_to_the_wall_apart_from_hits(app):
    sc = load_scenario("corridor")
    grid = sc.world.grid
    pose = np.array([8.5, 0.5, 0.0])
    rel = np.array([0.0, math.pi / 2, -math.pi / 2])
    wall = cast_rays(grid, pose[:2], pose[2] + rel, 8.0)
    z = np.column_stack([[wall[0] - 0.01, wall[1] + 1.5, 8.0], rel])  # hit, beyond, no return
    m = Measurement("laser", "range_finder", z, np.zeros(0, dtype=int))
    app.renderer.last_world = sc.world
    view = app.view
    surf = blank(app)
    map_view.draw_scan(surf, view, pose, m, 8.0, width=2, grid=grid)
    beyond = colour_count(surf, map_view.BEAM_BEYOND)
    assert beyond > 0 and colour_count(surf, map_view.BEAM_HIT) > 0
    # nothing of the scan drawn past the walls on the second and third beams
    px = pygame.surfarray.array3d(surf)
    for k in (1, 2):
        end = view.to_px(pose[:2] + wall[k] * np.array([math.cos(rel[k]), math.sin(rel[k])]))
        far = view.to_px(pose[:2] + (wall[k] + 0.6) * np.array([math.cos(rel[k]), math.sin(rel[k])]))
        assert tuple(px[int(far[0]), int(far[1])]) == (255, 255, 255), k
        assert np.hypot(*(far - end)) > 5
