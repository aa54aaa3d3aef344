"""The frame that carries a tick: the window's smooth drawing (the world's picture
kept between ticks, a tick's picture one frame later, the drawing in two phases) and the
heap settling change no result and no picture; only when the picture appears."""

from __future__ import annotations

import gc
import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import numpy as np
import pygame
import pytest

from beacon_sim.app import heap
from beacon_sim.app.strokes import JOINT_TURN, notched_joints
from beacon_sim.app.window import SCRIPTED_FRAME_S, App
from beacon_sim.core.geometry import covariance_ellipse
from beacon_sim.core.scenario import load_scenario
from beacon_sim.runs.live import Session

FILTERS = ["ekf", "pf", "histogram"]
PARAMS = {"pf": {"n_particles": 400}}


def make_app(smooth: bool, size=(960, 600)) -> App:
    s = Session(load_scenario("default"), FILTERS, None, PARAMS)
    s.toggle_autopilot()
    app = App(s, size, scripted=True)
    app.smooth = smooth
    return app


def world_pixels(app: App) -> np.ndarray:
    """The world's part of the screen (its last column is the panel's edge, drawn over it)."""
    area = pygame.Rect(app.view.area).clip(app.screen.get_rect())
    return pygame.surfarray.array3d(app.screen.subsurface(area))[:-1].copy()


def fresh_world(app: App) -> np.ndarray:
    """The world of the session's present state, drawn from scratch on a new surface."""
    surf = pygame.Surface(app.screen.get_size(), 0, app.screen)
    app.renderer.draw(surf, app.view, app.session, app.colours, app.show, None,
                      dashes=dict(app.dashes))
    area = pygame.Rect(app.view.area).clip(surf.get_rect())
    return pygame.surfarray.array3d(surf.subsurface(area))[:-1].copy()


def ran_or_spread_a_tick(app: App) -> bool:
    """Whether the frame showing the previous tick's picture ran a tick, or was the frame
    after one drawing more of its picture (``App._spread``)."""
    return app.ticks_this_frame > 0 or (app._pending is not None and app._pending[4])


def estimates(session: Session) -> dict[str, list[bytes]]:
    return {n: [m.tobytes() for m in t.means] + [c.tobytes() for c in t.covs]
            for n, t in session.runner.tracks.items()}


def test_smooth_frames_give_the_results_of_a_headless_session_bit_for_bit():
    app = make_app(smooth=True)
    app.settle_heap = True
    try:
        for _ in range(120):  # 2 s at 60 frames a second: 40 ticks of 0.05 s
            app.frame(SCRIPTED_FRAME_S)
        assert app.session.tick_count == 40
        headless = Session(load_scenario("default"), FILTERS, None, PARAMS)
        headless.toggle_autopilot()
        for _ in range(40):
            headless.tick()
        assert np.array_equal(app.session.true_pose, headless.true_pose)
        assert estimates(app.session) == estimates(headless)
        assert app.session.runner.tracks["pf"].means  # the filters did run
    finally:
        app.close()
        gc.unfreeze()


def test_every_frame_shows_the_present_or_the_previous_ticks_picture():
    """A kept picture equals a fresh drawing of the state it was drawn from; a frame that
    ran a tick may show the previous tick's picture (then the next frame shows the present),
    a change between ticks (a filter hidden) shows at once, and a banner drawn over the
    world for a few frames leaves no trace when it goes."""
    app = make_app(smooth=True)
    try:
        app.frame(SCRIPTED_FRAME_S)
        previous = fresh_world(app)
        assert np.array_equal(world_pixels(app), previous)
        stale_frames = 0
        for i in range(60):
            if i == 33:
                app.act("toggle2")  # hide pf between two ticks
            if i == 40:
                app.flash("a banner over the world")
                app.banner_until = app.now + 0.1  # 6 frames
            app.frame(SCRIPTED_FRAME_S)
            if i == 33:
                assert app.ticks_this_frame == 0
            if app.now < app.banner_until:
                assert app._on_screen is None
                continue
            present = fresh_world(app)
            shown = world_pixels(app)
            if app.world_stale:  # the frame of a tick, or the one after drawing more of it
                stale_frames += 1
                assert ran_or_spread_a_tick(app)
                assert np.array_equal(shown, previous)
                assert not np.array_equal(shown, present)  # the robot moved
            else:
                assert np.array_equal(shown, present), f"frame {i}"
                previous = present
        assert stale_frames >= 15  # one tick in three frames, almost every one deferred
        assert app.session.visible["pf"] is False
    finally:
        app.close()


def test_a_tick_that_comes_half_way_through_a_picture_is_spread_over_two_frames_too():
    """A frame whose tick lands while the previous tick's picture is half drawn keeps the
    picture before on the screen and draws only part of the new one (not all of it in one
    frame), once in a row; the frame after shows the present, as drawn from scratch."""
    app = make_app(smooth=True)
    try:
        for _ in range(12):
            app.frame(SCRIPTED_FRAME_S)
        while app._pending is not None:
            app.frame(SCRIPTED_FRAME_S)
        while app._pending is None:  # a tick's picture begun, the one before on the screen
            before = world_pixels(app)
            app.frame(SCRIPTED_FRAME_S)
        assert app.world_stale
        app.frame(app.session.scenario.dt)  # another tick lands half way
        assert app.ticks_this_frame == 1
        assert app._pending is not None and app._pending[3] < 5  # part of the new picture
        assert app.world_stale and np.array_equal(world_pixels(app), before)
        app.frame(app.session.scenario.dt)  # and another at once: not spread twice in a row
        assert app._pending is None
        assert np.array_equal(world_pixels(app), fresh_world(app))
    finally:
        app.close()


def test_ticks_six_frames_apart_spread_a_picture_over_three_frames_and_it_ends_as_drawn_afresh():
    """two_rooms ticks every 0.1 s: six frames apart at 60 FPS. The tick's frame draws the
    first layers, the next frame some more (no tick, the previous picture still on the
    screen), the third shows the present exactly as drawn from scratch; every frame shows
    the present or the previous tick's picture."""
    s = Session(load_scenario("two_rooms"), ["ekf", "pf"], None, {"pf": {"n_particles": 400}})
    s.toggle_autopilot()
    app = App(s, (960, 600), scripted=True)
    app.smooth = True
    try:
        for _ in range(30):
            app.frame(SCRIPTED_FRAME_S)
        while app.world_stale:
            app.frame(SCRIPTED_FRAME_S)
        previous, spread = fresh_world(app), 0
        for i in range(60):
            ticks_before = app.session.tick_count
            app.frame(SCRIPTED_FRAME_S)
            shown = world_pixels(app)
            if app.world_stale:
                assert np.array_equal(shown, previous), f"frame {i}"
                if app.ticks_this_frame == 0:  # the frame after a tick's: more of its picture
                    assert app.session.tick_count == ticks_before and app._pending[4]
                    spread += 1
            else:
                present = fresh_world(app)
                assert np.array_equal(shown, present), f"frame {i}"
                previous = present
        assert spread >= 8  # ten ticks: (almost) each picture over three frames
    finally:
        app.close()


def test_the_world_is_drawn_as_without_smooth_and_a_screenshot_shows_the_present(tmp_path):
    plain, smooth = make_app(smooth=False), make_app(smooth=True)
    try:
        for i in range(60):  # until a frame that ran a tick leaves smooth a tick behind
            plain.frame(SCRIPTED_FRAME_S)
            smooth.frame(SCRIPTED_FRAME_S)
            if i >= 40 and smooth.world_stale:
                break
        assert smooth.world_stale
        assert estimates(plain.session) == estimates(smooth.session)
        smooth.save_screenshot(tmp_path / "smooth.png")
        plain.save_screenshot(tmp_path / "plain.png")
        a = pygame.surfarray.array3d(pygame.image.load(str(tmp_path / "smooth.png")))
        b = pygame.surfarray.array3d(pygame.image.load(str(tmp_path / "plain.png")))
        assert np.array_equal(a, b)
    finally:
        plain.close()
        smooth.close()


def test_run_switches_smooth_on_for_its_loop_and_ends_on_the_present():
    app = make_app(smooth=False)
    try:
        app.run(45)  # frame 45 runs a tick
        assert app.smooth is False and not app.world_stale
        assert gc.get_freeze_count() == 0  # the loop released the heap it froze
        assert np.array_equal(world_pixels(app), fresh_world(app))
    finally:
        app.close()
        gc.unfreeze()


def test_the_heap_settles_at_the_start_then_every_period_on_a_frame_without_a_tick():
    gc.unfreeze()
    try:
        settler = heap.HeapSettler(every_s=1.0)
        assert settler.offer(0.0, busy=True)  # the first frame, whatever it ran
        assert gc.get_freeze_count() > 0
        assert not settler.offer(0.5, busy=False)
        assert not settler.offer(1.2, busy=True)  # due, but that frame ran a tick
        assert settler.offer(1.25, busy=False)
        assert not settler.offer(2.0, busy=False)
        assert settler.offer(2.3, busy=False)
        settler.release()
        assert gc.get_freeze_count() == 0
        assert settler.offer(2.4, busy=True)  # settled afresh after a release
    finally:
        gc.unfreeze()


def test_a_settle_still_frees_cycles_made_before_it():
    import weakref

    class Node:
        pass

    gc.unfreeze()
    try:
        a, b = Node(), Node()
        a.other, b.other = b, a  # a cycle: only the collector frees it
        ref = weakref.ref(a)
        del a, b
        heap.settle(full=False)
        assert ref() is None
    finally:
        gc.unfreeze()


def test_notched_joints_are_the_turns_and_the_changes_of_stroke_axis():
    line = np.array([[0.0, 0.0], [10.0, 1.0], [20.0, 2.0], [30.0, 3.0]])
    assert not notched_joints(line).any()
    square = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0], [0.0, 0.0]])
    assert notched_joints(square).all()
    turn = np.radians(np.array([0.0, 5.0, 15.0]))  # segments at 0, 5 and 15 degrees
    pts = np.vstack([[0.0, 0.0], np.cumsum(20 * np.c_[np.cos(turn), np.sin(turn)], axis=0)])
    assert notched_joints(pts).tolist() == [5 > np.degrees(JOINT_TURN),
                                            10 > np.degrees(JOINT_TURN)]
    # 40 -> 50 degrees: a small turn, but the strokes change from along y to along x
    steep = np.radians(np.array([40.0, 44.0, 48.0]))
    pts = np.vstack([[0.0, 0.0], np.cumsum(20 * np.c_[np.cos(steep), np.sin(steep)], axis=0)])
    assert notched_joints(pts).tolist() == [False, True]
    assert notched_joints(np.array([[0.0, 0.0], [0.0, 0.0], [5.0, 0.0]])).tolist() == [True]
    # a 96-point ellipse, axes 200 and 90 px: the 4 vertices where the slope crosses 45
    # degrees and the sharper turns at the ends of the long axis (over 8 degrees there)
    ell = covariance_ellipse(np.array([300.0, 300.0]), np.diag([200.0, 90.0]) ** 2, 1.0, 96)
    k = int(notched_joints(np.vstack([ell, ell[:1]])).sum())
    assert 4 <= k <= 16


@pytest.mark.parametrize("dash", [None, (5, 8)])
def test_polyline_with_fewer_round_caps_looks_the_same(dash):
    from beacon_sim.app import strokes

    ell = covariance_ellipse(np.array([320.0, 240.0]), np.diag([180.0, 70.0]) ** 2, 1.0, 96)
    surfs = []
    for all_caps in (False, True):
        surf = pygame.Surface((640, 480))
        surf.fill((255, 255, 255))
        if all_caps:
            real = strokes.notched_joints
            strokes.notched_joints = lambda pts: np.ones(len(pts) - 2, dtype=bool)
            try:
                strokes.polyline(surf, (200, 0, 0), ell, 4, dash, closed=True)
            finally:
                strokes.notched_joints = real
        else:
            strokes.polyline(surf, (200, 0, 0), ell, 4, dash, closed=True)
        surfs.append(pygame.surfarray.array3d(surf))
    drawn = (surfs[1] != 255).any(axis=2).sum()
    differ = (surfs[0] != surfs[1]).any(axis=2).sum()
    assert drawn > 1000
    assert differ <= 0.002 * drawn  # a handful of pixels of a 4 px wide ring


def test_particles_through_one_flat_index_equal_the_two_index_path():
    """The contiguous surface takes the flat-index path, a subsurface (rows padded to the
    parent's pitch) the (x, y) path; the pixels are the same."""
    from beacon_sim.app.assets import load_fonts
    from beacon_sim.app.render import View, WorldRenderer

    pygame.font.init()
    renderer = WorldRenderer(load_fonts(400, 640))
    view = View((0.0, 0.0, 12.0, 8.0), (0, 0, 600, 400))
    rng = np.random.default_rng(7)
    poses = np.c_[rng.normal(6, 2.5, 3000), rng.normal(4, 2.0, 3000), rng.normal(0, 1, 3000)]
    weights = rng.random(3000)
    weights /= weights.sum()
    out = []
    for padded in (False, True):
        parent = pygame.Surface((640 if padded else 600, 400))
        surf = parent.subsurface(pygame.Rect(0, 0, 600, 400)) if padded else parent
        assert pygame.surfarray.pixels2d(surf).T.flags.c_contiguous is not padded
        surf.fill((250, 250, 240))
        surf.set_clip(pygame.Rect(view.area))
        renderer.particles(surf, view, poses, (200, 100, 150), weights)
        out.append(pygame.surfarray.array3d(surf))
    drawn = (out[0] != np.array([250, 250, 240])).any(axis=2).sum()
    assert 5000 < drawn < 600 * 400 // 2  # the particles were drawn, the floor shows
    assert np.array_equal(out[0], out[1])


def test_the_team_window_keeps_its_worlds_and_its_legends_picture_and_shows_the_present():
    """A team's world is kept between ticks as a single robot's is (drawn once a tick, not
    every frame), each frame showing the present or the previous tick's picture; the
    legend under the world is a kept picture with the pixels of a fresh drawing."""
    from beacon_sim.core.scenario import load_team_scenario

    s = Session(load_team_scenario("team_sparse"), ["independent", "centralised", "ci"])
    s.toggle_autopilot()
    app = App(s, (1280, 800), scripted=True)
    app.smooth = True
    drawn = []
    team_phases = app.renderer.team_phases

    def counted(*args, **kwargs):
        drawn.append(app.frames)
        return team_phases(*args, **kwargs)

    app.renderer.team_phases = counted
    try:
        app.frame(SCRIPTED_FRAME_S)
        previous = fresh_world(app)
        stale = 0
        for _ in range(60):
            app.frame(SCRIPTED_FRAME_S)
            present = fresh_world(app)
            shown = world_pixels(app)
            if app.world_stale:
                stale += 1
                assert ran_or_spread_a_tick(app)
                assert np.array_equal(shown, previous)
            else:
                assert np.array_equal(shown, present), f"frame {app.frames}"
                previous = present
        ticks = app.session.tick_count
        assert stale >= 5
        # one drawing a tick (and the first frame's), each fresh_world call aside
        assert len(drawn) - 61 <= ticks + 1 < 61
        area = app.legend_area()
        legend = pygame.Surface(area.size, 0, app.screen)
        names = [n for n in s.names if s.visible[n]]
        app.hud._draw_world_legend(legend, legend.get_rect(), names, app.colours, app.dashes,
                                   app.renderer.lw)
        assert np.array_equal(pygame.surfarray.array3d(app.screen.subsurface(area)),
                              pygame.surfarray.array3d(legend))
    finally:
        app.close()


def test_the_team_window_leaves_its_world_on_the_screen_until_something_covers_or_changes_it():
    """Between ticks a team's world is not blitted again when the screen still holds it (as a
    single robot's); whatever covers it (the help, a banner) or changes it (Tab, a filter
    hidden) brings the right picture back: every plain frame shows the present or the
    previous tick's world."""
    from beacon_sim.core.scenario import load_team_scenario

    s = Session(load_team_scenario("team_sparse"), ["centralised", "ci"])
    s.toggle_autopilot()
    app = App(s, (1024, 768), scripted=True)
    app.smooth = True
    events = {5: "next_robot", 12: "help", 16: "help", 23: "toggle1", 31: "toggle1",
              38: "next_robot", 45: "help", 46: "next_robot", 50: "help"}
    try:
        app.frame(SCRIPTED_FRAME_S)
        previous = fresh_world(app)
        kept = stale = 0
        for i in range(70):
            if i in events:
                app.act(events[i])
                if events[i] == "next_robot":  # its banner ("driving: ...") for 3 frames
                    app.banner_until = app.now + 0.05
            if i == 56:
                app.flash("a banner over the world")
                app.banner_until = app.now + 0.1  # 6 frames
            app.frame(SCRIPTED_FRAME_S)
            if app.help or app.now < app.banner_until:
                assert app._on_screen is None
                if not app.world_stale:
                    previous = fresh_world(app)
                continue
            kept += app._on_screen is not None
            present = fresh_world(app)
            shown = world_pixels(app)
            if app.world_stale:
                stale += 1
                assert ran_or_spread_a_tick(app)
                assert np.array_equal(shown, previous), f"frame {i}"
            else:
                assert np.array_equal(shown, present), f"frame {i}"
                previous = present
        assert kept >= 40 and stale >= 5
        assert s.driven == 3 % s.n_robots and s.visible["centralised"]
    finally:
        app.close()


def test_with_the_filters_on_the_worker_a_teams_tick_is_drawn_over_three_frames_as_afresh():
    """team_sparse ticks every 0.05 s, three frames apart, with its four default filters on
    the worker (as the window runs them): the frame that shows a finished tick draws the
    first layers, the next some more, the third (which also steps the simulation of the
    next tick) shows the tick's world exactly as drawn from scratch; every frame shows the
    present or the previous tick's world."""
    from beacon_sim.core.scenario import load_team_scenario

    team = load_team_scenario("team_sparse")
    s = Session(team, list(team.default_filters))
    s.toggle_autopilot()
    app = App(s, (1280, 800), scripted=True)
    app.smooth = True
    s.start_worker()
    try:
        for _ in range(30):
            app.frame(SCRIPTED_FRAME_S)
            s.settle_worker()  # the worker's tick done before the next frame shows it
        previous, spread = fresh_world(app), 0
        for i in range(60):
            app.frame(SCRIPTED_FRAME_S)
            s.settle_worker()
            shown = world_pixels(app)
            if app.world_stale:
                assert ran_or_spread_a_tick(app), f"frame {i}"
                assert np.array_equal(shown, previous), f"frame {i}"
                spread += app.ticks_this_frame == 0
            else:
                present = fresh_world(app)
                assert np.array_equal(shown, present), f"frame {i}"
                previous = present
        assert spread >= 12  # twenty ticks: (almost) each picture over three frames
        assert s.tick_count >= 18
    finally:
        app.close()
