"""Metres -> pixels, the grid spacing, particles through pixel arrays, the heat map, and the
fixed-step clock, checked against hand computations."""

from __future__ import annotations

import math
import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import numpy as np
import pygame
import pytest

from beacon_sim.app import shapes
from beacon_sim.app.loop import SPEEDS, StepClock
from beacon_sim.app.palette import OKABE_ITO, filter_colours, filter_styles, particle_colours
from beacon_sim.app.render import View, WorldRenderer
from beacon_sim.app.view import nice_step
from beacon_sim.core.types import Measurement
from beacon_sim.filters.base import GridBelief


def test_view_fits_the_world_and_flips_y():
    v = View((0.0, 0.0, 12.0, 8.0), (0, 0, 900, 800))
    # Width limits: (900 - 2 * 44) / 12 = 67.666 px/m; height would allow 89 px/m.
    assert v.scale == pytest.approx((900 - 88) / 12)
    # The world's centre (6, 4) sits at the area's centre; y up on the world is up on screen.
    np.testing.assert_allclose(v.to_px([6.0, 4.0]), [450.0, 400.0])
    np.testing.assert_allclose(v.to_px([0.0, 0.0]), [450 - 6 * v.scale, 400 + 4 * v.scale])
    np.testing.assert_allclose(v.to_px([12.0, 8.0]), [450 + 6 * v.scale, 400 - 4 * v.scale])
    pts = np.array([[1.0, 2.0], [-3.0, 7.5], [11.9, 0.1]])
    np.testing.assert_allclose(v.to_world(v.to_px(pts)), pts)


def test_zoom_keeps_the_point_under_the_mouse_and_pan_moves_the_picture():
    v = View((0.0, 0.0, 10.0, 10.0), (0, 0, 800, 800))
    at = np.array([200.0, 300.0])
    w = v.to_world(at)
    s = v.scale
    v.zoom(2.0, at)
    assert v.scale == pytest.approx(2 * s)
    np.testing.assert_allclose(v.to_world(at), w)
    p = v.to_px([5.0, 5.0])
    v.pan(30, -20)
    np.testing.assert_allclose(v.to_px([5.0, 5.0]), p + np.array([30.0, -20.0]))
    v.fit()
    assert v.scale == pytest.approx(s)


def test_grid_step_is_1_2_5_and_at_least_the_minimum_spacing():
    assert nice_step(67.0) == 2.0  # 70 px / 67 px/m = 1.04 m -> 2 m
    assert nice_step(70.0) == 1.0
    assert nice_step(300.0) == 0.5  # 0.233 m -> 0.5
    assert nice_step(10.0) == 10.0
    assert nice_step(1.0) == 100.0


def test_particles_are_written_as_blocks_through_the_pixel_array():
    """3x3 px blocks up to 20,000 particles (seen on a projector), 2x2 above, in the filter's
    colour darkened to 4.5:1 against the floor."""
    surf = pygame.Surface((400, 400))
    surf.fill((255, 255, 255))
    v = View((0.0, 0.0, 4.0, 4.0), (0, 0, 400, 400))  # scale (400 - 88) / 4 = 78 px/m
    poses = np.array([[1.0, 1.0, 0.0], [3.0, 2.0, 1.0], [50.0, 50.0, 0.0]])  # last one off-screen
    WorldRenderer({}).particles(surf, v, poses, (0, 114, 178))
    shade = particle_colours((0, 114, 178))[0]
    for x, y in ([1.0, 1.0], [3.0, 2.0]):
        px = int(200 + (x - 2.0) * 78)
        py = int(200 - (y - 2.0) * 78)
        for dx in (0, 1, 2):
            for dy in (0, 1, 2):
                assert tuple(surf.get_at((px + dx, py + dy)))[:3] == shade
    arr = pygame.surfarray.array3d(surf)
    blue = np.all(arr == shade, axis=2)
    assert blue.sum() == 18


def test_grid_belief_tints_its_cells_only():
    pygame.display.init()
    surf = pygame.Surface((400, 400))
    surf.fill((255, 255, 255))
    v = View((0.0, 0.0, 4.0, 4.0), (0, 0, 400, 400))
    prob = np.zeros((8, 8))
    prob[1, 6] = 1.0  # cell x in [0.5, 1.0), y in [3.0, 3.5)
    r = WorldRenderer({})
    r._heat(surf, v, "hist", GridBelief(prob, (0.0, 0.0), 0.5), (213, 94, 0), tick=1)
    inside = v.to_px([0.75, 3.25])
    outside = v.to_px([0.75, 1.25])
    c_in = tuple(surf.get_at((int(inside[0]), int(inside[1]))))[:3]
    c_out = tuple(surf.get_at((int(outside[0]), int(outside[1]))))[:3]
    assert c_out == (255, 255, 255)
    # One cell holds everything: max / mean = 64, so the peak alpha is 60 + 140 (1 - e^-21) = 200.
    a = 200 / 255
    expected = [round(255 * (1 - a) + c * a) for c in (213, 94, 0)]
    assert np.allclose(c_in, expected, atol=3)


def test_wedge_spans_plus_minus_the_half_angle():
    pose = np.array([1.0, 2.0, 0.5])
    w = shapes.wedge(pose, 0.3, 2.0, n=11)
    np.testing.assert_allclose(w[0], [1.0, 2.0])
    np.testing.assert_allclose(w[-1], [1.0, 2.0])
    ang = np.arctan2(w[1:-1, 1] - 2.0, w[1:-1, 0] - 1.0)
    np.testing.assert_allclose([ang.min(), ang.max()], [0.2, 0.8])
    np.testing.assert_allclose(np.hypot(w[1:-1, 0] - 1.0, w[1:-1, 1] - 2.0), 2.0)
    full = shapes.wedge(pose, 4.0, 1.0)
    np.testing.assert_allclose(np.hypot(full[:, 0] - 1.0, full[:, 1] - 2.0), 1.0)


def test_rays_follow_the_measured_bearing_and_range():
    pose = np.array([1.0, 1.0, math.pi / 2])  # facing +y
    m = Measurement("b", "range_bearing", np.array([[2.0, -math.pi / 2]]), np.array([1]))
    seg = shapes.rays(pose, m, np.zeros((1, 2)), far=50.0)
    np.testing.assert_allclose(seg[0], [[1.0, 1.0], [3.0, 1.0]], atol=1e-12)  # to the right
    m = Measurement("b", "bearing", np.array([[math.pi / 2]]), np.array([1]))
    seg = shapes.rays(pose, m, np.zeros((1, 2)), far=50.0)
    np.testing.assert_allclose(seg[0, 1], [-49.0, 1.0], atol=1e-9)  # to the left, 50 m


def test_chassis_points_forward():
    body, wheels = shapes.chassis(np.array([0.0, 0.0, math.pi]), 1.0)
    assert body[0] == pytest.approx([-1.0, 0.0])  # the nose, along theta = pi
    assert wheels.shape == (2, 4, 2)


def test_clock_spends_real_time_in_whole_ticks_whatever_the_frame_rate():
    rng = np.random.default_rng(5)
    for speed in (0.25, 1.0, 8.0):
        c = StepClock(0.05, max_steps_per_frame=1000)
        c.speed_index = SPEEDS.index(speed)
        frames = rng.uniform(0.001, 0.04, 2000)
        total = sum(c.advance(f) for f in frames)
        assert total == math.floor(frames.sum() * speed / 0.05 + 1e-6) or \
            total == math.floor(frames.sum() * speed / 0.05 + 1e-6) - 1


def test_clock_caps_ticks_per_frame_and_drops_the_rest():
    c = StepClock(0.05, max_steps_per_frame=4)
    assert c.advance(1.0) == 4  # 20 ticks due, 4 run
    assert c.dropped_s == pytest.approx(16 * 0.05)
    assert c.advance(0.05) == 1


def test_clock_pause_and_single_step():
    c = StepClock(0.1)
    c.toggle_pause()
    assert c.advance(5.0) == 0
    c.single_step()
    c.single_step()
    assert c.advance(0.0) == 2
    assert c.advance(1.0) == 0
    c.toggle_pause()
    c.single_step()  # ignored while running
    assert c.advance(0.1) == 1
    for _ in range(10):
        c.faster()
    assert c.speed == 8.0
    for _ in range(10):
        c.slower()
    assert c.speed == SPEEDS[0] == 0.1
    c.set_speed(0.3)
    assert c.speed == 0.25


def test_filter_colours_are_okabe_ito_by_kind_and_dead_reckoning_grey():
    cols = filter_colours(["ekf", "dead_reckoning", "ukf", "pf"])
    assert {cols["ekf"], cols["ukf"], cols["pf"]} <= set(OKABE_ITO)
    assert cols == filter_colours(["pf", "ukf", "dead_reckoning", "ekf"])  # kind, not order
    assert cols["dead_reckoning"][0] == cols["dead_reckoning"][1] == cols["dead_reckoning"][2]


def test_every_filter_kind_has_its_own_colour_or_line_style():
    names = ["kf", "ekf", "ukf", "pf", "histogram", "dead_reckoning", "Mine", "ekf'"]
    styles = filter_styles(names)
    assert len(set(styles.values())) == len(names)
    assert styles["ekf"][1] != styles["ukf"][1]  # they agree: one solid, one dashed
    assert styles["ekf'"][0] == styles["ekf"][0]


def test_a_sensor_disc_tints_its_range_and_is_the_same_picture_wherever_the_robot_is():
    """A whole disc (no walls, full field of view) multiplies the floor by the sensor's tint
    inside its range, leaves it outside, and is drawn from one kept tint: moved by whole
    pixels with the robot, the same pixels moved."""
    from types import SimpleNamespace

    from beacon_sim.app import palette

    v = View((0.0, 0.0, 10.0, 10.0), (0, 0, 600, 600))
    spec = SimpleNamespace(max_range=2.0, fov=2 * math.pi, occluded_by_walls=False)
    r = WorldRenderer({})
    pictures = []
    for x in (4.0, 4.0 + 3 / v.scale):  # three pixels to the right
        surf = pygame.Surface((600, 600))
        surf.fill((200, 200, 200))
        r.sensor_discs(surf, v, [spec], np.array([x, 5.0, 0.3]))
        pictures.append(pygame.surfarray.array3d(surf))
    c = v.to_px(np.array([4.0, 5.0]))
    radius = 2.0 * v.scale
    tinted = tuple(round(200 * t / 255) for t in palette.SENSOR_FILL)
    for dx, dy in ((0.0, 0.0), (radius - 4, 0.0), (0.0, -(radius - 4)), (0.6 * radius, 0.6 * radius)):
        assert tuple(pictures[0][int(c[0] + dx), int(c[1] + dy)]) == tinted
    for dx, dy in ((radius + 4, 0.0), (0.0, radius + 4), (0.75 * radius, 0.75 * radius)):
        assert tuple(pictures[0][int(c[0] + dx), int(c[1] + dy)]) == (200, 200, 200)
    assert np.array_equal(pictures[0][:-3], pictures[1][3:])  # the same disc, 3 px on
    assert len(r._disc_tints) == 1
