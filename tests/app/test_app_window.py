"""The window under SDL's dummy driver: keys, pause, kidnaps, screenshots, help, and a run
driven through the window equal to the headless simulation fed the same commands."""

from __future__ import annotations

import math
import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import numpy as np
import pygame
import pytest

from beacon_sim.app import controls, palette
from beacon_sim.app.view import ipx
from beacon_sim.app.window import App
from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.core.types import Control
from beacon_sim.hosting.loading import build_filter
from beacon_sim.hosting.runner import FilterRunner
from beacon_sim.io.recording import RECORDINGS_DIR
from beacon_sim.runs.live import Session
from beacon_sim.runs.user_commands import apply_commands


def make_app(scenario="default", filters=("dead_reckoning",), seed=None, size=(1280, 800)):
    sc = load_scenario(scenario)
    return App(Session(sc, list(filters), seed), size, scripted=True)


def key(k, up=True):
    pygame.event.post(pygame.event.Event(pygame.KEYDOWN, key=k, mod=0, unicode="", scancode=0))
    if up:
        pygame.event.post(pygame.event.Event(pygame.KEYUP, key=k, mod=0, unicode="", scancode=0))


def click(start, end, button=1):
    pygame.event.post(pygame.event.Event(pygame.MOUSEBUTTONDOWN, pos=start, button=button))
    pygame.event.post(pygame.event.Event(pygame.MOUSEBUTTONUP, pos=end, button=button))


def frames(app, n):
    app.run(app.frames + n)


@pytest.fixture
def app():
    a = make_app()
    yield a
    a.close()


def test_keys_change_v_and_omega_by_the_scenario_steps_and_x_stops(app):
    lim = app.session.scenario.keyboard  # default.toml: v_step 0.1, omega_step 0.2
    assert (lim.v_step, lim.omega_step) == (0.1, 0.2)
    for _ in range(3):
        key(pygame.K_w)
    key(pygame.K_a)
    key(pygame.K_a)
    frames(app, 3)
    assert app.session.keyboard.control == Control(0.3, 0.4)
    key(pygame.K_s)
    key(pygame.K_d)
    frames(app, 3)
    assert app.session.keyboard.control == Control(0.2, 0.2)
    # The ticks run after the keys use the command: 3 frames at 1/60 s = one 0.05 s tick.
    assert app.session.controls[-1] == Control(0.2, 0.2)
    key(pygame.K_x)
    frames(app, 3)
    assert app.session.keyboard.control == Control(0.0, 0.0)
    assert app.session.controls[-1] == Control(0.0, 0.0)


def test_limits_and_held_keys_repeat_only_for_driving(app):
    for _ in range(25):  # held W: repeated KEYDOWN without KEYUP, clamped at v_max = 1.0
        key(pygame.K_w, up=False)
    key(pygame.K_d, up=False)
    for _ in range(5):  # held Space: pauses once, the repeats are ignored
        key(pygame.K_SPACE, up=False)
    frames(app, 1)
    assert app.session.keyboard.v == 1.0
    assert app.session.keyboard.omega == pytest.approx(-0.2)
    assert app.clock.paused


def test_pause_freezes_simulated_time_and_dot_steps_once(app):
    frames(app, 60)  # 1 s at x1 with dt = 0.05 s
    assert app.session.sim.tick == 20
    key(pygame.K_SPACE)
    frames(app, 90)
    assert app.session.sim.tick == 20
    key(pygame.K_PERIOD)
    frames(app, 1)
    assert app.session.sim.tick == 21
    frames(app, 30)
    assert app.session.sim.tick == 21
    key(pygame.K_SPACE)
    key(pygame.K_PLUS)  # x2
    frames(app, 30)
    assert app.session.sim.tick == 21 + 20


def test_k_kidnaps_to_a_random_pose(app):
    frames(app, 3)
    before = app.session.true_pose.copy()
    key(pygame.K_k)
    frames(app, 3)
    step = app.session.last_step
    kidnaps = [e for e in step.steps[0].events if e.kind == "kidnap"]
    assert len(kidnaps) == 1 and "user" in kidnaps[0].detail
    assert np.hypot(*(app.session.true_pose[:2] - before[:2])) > 0.1
    assert app.session.commands[step.tick] == [{"kind": "kidnap"}]


def test_click_kidnaps_to_the_point_and_drag_sets_the_heading(app):
    frames(app, 3)
    target = np.array([8.0, 5.0])
    p = app.view.to_px(target)
    start = (ipx(p[0]), ipx(p[1]))
    click(start, (start[0], start[1] - 60))  # drag up on screen: heading north (+pi/2)
    frames(app, 3)
    step = app.session.last_step
    assert any(e.kind == "kidnap" for e in step.steps[0].events)
    pose = app.session.true_pose
    assert np.hypot(*(pose[:2] - target)) <= 1.0 / app.view.scale  # within a pixel
    assert pose[2] == pytest.approx(math.pi / 2)
    # A plain click keeps the heading.
    p = app.view.to_px(np.array([3.0, 6.0]))
    start = (ipx(p[0]), ipx(p[1]))
    click(start, start)
    frames(app, 3)
    assert app.session.true_pose[2] == pytest.approx(math.pi / 2)
    assert np.hypot(*(app.session.true_pose[:2] - [3.0, 6.0])) <= 1.0 / app.view.scale


def test_screenshot_has_the_robot_colour_where_the_robot_is(tmp_path):
    app = make_app()
    try:
        key(pygame.K_1)  # hide the filter so that only the robot is at the robot's place
        for _ in range(4):
            key(pygame.K_w)
        frames(app, 60)
        path = tmp_path / "shot.png"
        app.save_screenshot(path)
        img = pygame.image.load(str(path))
        assert img.get_size() == (1280, 800)
        x, y = app.view.to_px(app.session.true_pose[:2])
        assert tuple(img.get_at((ipx(x), ipx(y))))[:3] == palette.ROBOT
        # Far from the robot (top right of the world, no beacon there) it is not robot-coloured.
        fx, fy = app.view.to_px(np.array([9.0, 4.5]))
        assert tuple(img.get_at((int(fx), int(fy))))[:3] != palette.ROBOT
    finally:
        app.close()


def test_play_command_writes_the_screenshot(tmp_path):
    from beacon_sim.cli.main import main

    path = tmp_path / "play.png"
    assert main(["play", "default", "--filter", "dead_reckoning", "--frames", "5", "--no-record",
                 "--screenshot", str(path), "--size", "800x600"]) == 0
    assert pygame.image.load(str(path)).get_size() == (800, 600)


def test_help_overlay_lists_every_binding_of_the_table(app):
    key(pygame.K_h)
    frames(app, 1)
    assert app.help
    assert app.hud.help_drawn == [(b.keys, b.description) for b in controls.BINDINGS]
    key(pygame.K_F1)
    frames(app, 1)
    assert not app.help


def test_every_key_of_the_table_reaches_its_action(app, monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)  # F12 writes here
    seen = []
    real_act = app.act

    def act(action):
        seen.append(action)
        if action != "quit":
            real_act(action)

    monkeypatch.setattr(app, "act", act)
    expected = []
    for b in controls.BINDINGS:
        for code in b.codes:
            key(code)
            name = b.action
            if name.endswith("*"):
                name = name[:-1] + str(controls.FILTER_KEYS.index(code) + 1)
            expected.append(name)
    frames(app, 1)
    assert seen == expected
    assert list(tmp_path.glob("screenshots/*.png"))


def test_unknown_action_is_an_error(app):
    with pytest.raises(ValueError):
        app.act("no-such-action")


def test_window_run_equals_the_headless_simulation_fed_the_same_commands():
    app = make_app(filters=("dead_reckoning", "dead_reckoning"))
    s = app.session
    try:
        key(pygame.K_w)
        key(pygame.K_w)
        frames(app, 40)
        key(pygame.K_a)
        key(pygame.K_PLUS)
        key(pygame.K_PLUS)  # x4: several ticks per frame
        frames(app, 50)
        key(pygame.K_k)
        key(pygame.K_r)
        key(pygame.K_d)
        key(pygame.K_d)
        frames(app, 37)
        p = app.view.to_px(np.array([6.0, 3.0]))
        click((int(p[0]), int(p[1])), (int(p[0]) + 50, int(p[1]) + 20))
        key(pygame.K_2)
        frames(app, 61)
        key(pygame.K_MINUS)
        key(pygame.K_MINUS)
        key(pygame.K_MINUS)  # x0.5
        frames(app, 45)
    finally:
        app.close()
    n = s.sim.tick
    assert n == len(s.controls) > 100
    assert {c["kind"] for cmds in s.commands.values() for c in cmds} == \
        {"kidnap", "reset", "toggle"}

    sc = s.scenario
    sim = Simulation(sc, sc.seed)
    filters = {name: build_filter("dead_reckoning", sc, sc.seed, name=name) for name in s.names}
    runner = FilterRunner(filters)
    for k in range(1, n + 1):
        apply_commands(s.commands.get(k, []), sim, filters, sc)
        runner.feed(sim.step(s.controls[k - 1]))
    assert sim.truth_checksum == s.sim.truth_checksum
    for name in s.names:
        np.testing.assert_array_equal(runner.tracks[name].means[-1], s.runner.tracks[name].means[-1])
    # The truth moved: not a trivial match of a robot standing still.
    assert np.hypot(*(sim.pose[:2] - np.array(sc.initial_pose[:2]))) > 0.3


def test_failing_filter_is_switched_off_and_its_message_kept(tmp_path):
    bad = tmp_path / "bad_filter.py"
    bad.write_text(
        "from beacon_sim.filters.gaussian.dead_reckoning import DeadReckoning\n"
        "class Bad(DeadReckoning):\n"
        "    def update(self, measurements):\n"
        "        if measurements:\n"
        "            raise RuntimeError('student bug here')\n")
    app = make_app(filters=("dead_reckoning", f"{bad}:Bad"))
    try:
        frames(app, 30)
        st = app.session.status["Bad"]
        assert st.failed and "student bug here" in st.failed
        assert "student bug here" in app.session.runner.tracks["Bad"].traceback
        assert app.session.status["dead_reckoning"].failed is None
    finally:
        app.close()


def test_resize_refits_the_world():
    app = make_app(size=(1000, 700))
    try:
        pygame.display.set_mode((1400, 900), pygame.RESIZABLE)
        pygame.event.post(pygame.event.Event(pygame.VIDEORESIZE, size=(1400, 900), w=1400, h=900))
        frames(app, 1)
        assert app.screen.get_size() == (1400, 900)
        x0, y0, x1, y1 = app.view.visible_world()
        assert x0 <= 0 and y0 <= 0 and x1 >= 12 and y1 >= 8
        assert app.view.area[2] + app.panel_rect.width == 1400
    finally:
        app.close()


def test_the_window_records_what_it_ran(tmp_path, monkeypatch):
    import json

    from beacon_sim.runs.live import make_recorder

    monkeypatch.chdir(tmp_path)
    sc = load_scenario("default")
    recorder, path = make_recorder(sc, sc.seed, ["dead_reckoning"], {})
    assert recorder is not None and path.parent.name == RECORDINGS_DIR
    app = App(Session(sc, ["dead_reckoning"], None, {}, recorder), (1000, 700), scripted=True)
    try:
        key(pygame.K_w)
        key(pygame.K_a)
        frames(app, 30)
        key(pygame.K_k)
        frames(app, 30)
    finally:
        app.close()
    lines = [json.loads(x) for x in path.read_text().splitlines()]
    ticks = [x for x in lines if x["type"] == "tick"]
    assert [t["k"] for t in ticks] == list(range(1, app.session.sim.tick + 1))
    assert [tuple(t["u"]) for t in ticks] == [(c.v, c.omega) for c in app.session.controls]
    assert lines[-1]["type"] == "end" and lines[-1]["checksum"] == app.session.sim.truth_checksum
    assert sum(1 for t in ticks if t.get("c") == [{"kind": "kidnap"}]) == 1


def test_autopilot_option_drives_the_scenario_driver(tmp_path, monkeypatch):
    from beacon_sim.cli.main import main
    from beacon_sim.io.recording import load_recording

    monkeypatch.chdir(tmp_path)  # the recording goes to ./recordings
    shot = tmp_path / "auto.png"
    assert main(["play", "default", "--filter", "dead_reckoning", "--autopilot", "--frames", "120",
                 "--screenshot", str(shot)]) == 0
    assert shot.is_file()
    (path,) = (tmp_path / "recordings").glob("*.jsonl")
    ticks = load_recording(path).ticks
    assert len(ticks) > 30 and all(t.control.v > 0 for t in ticks[5:])  # the tour drives on
    # Without a driver there is nothing to hand the wheel to: one-line error, exit 2.
    bad = tmp_path / "kb.toml"
    bad.write_text('[world]\nbounds = [0, 0, 5, 5]\n[robot]\ninitial_pose = [1, 1, 0]\n')
    assert main(["play", str(bad), "--filter", "dead_reckoning", "--autopilot", "--frames", "1",
                 "--no-record"]) == 2
