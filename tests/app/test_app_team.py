"""The team window under SDL's dummy driver: every robot and each team
filter's belief of each robot drawn, Tab switches the driven robot, the same key presses
give the same truth whatever the frame rate, a failing team filter is switched off with its
message while the others go on, and ``beacon-sim play TEAM`` opens it."""

from __future__ import annotations

import os
from pathlib import Path

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import numpy as np
import pygame
import pytest

from beacon_sim.app import palette
from beacon_sim.app.view import ipx
from beacon_sim.app.window import App
from beacon_sim.core.scenario import load_team_scenario
from beacon_sim.core.team import TeamSimulation
from beacon_sim.core.types import Control
from beacon_sim.runs.live import KEEP_ESTIMATES, Session

FILTERS = ["independent", "centralised", "ci"]


def make_app(filters=FILTERS, seed=None, autopilot=False):
    s = Session(load_team_scenario("team_sparse"), list(filters), seed)
    if autopilot:
        s.toggle_autopilot()
    return App(s, (1280, 800), scripted=True)


def key(k):
    pygame.event.post(pygame.event.Event(pygame.KEYDOWN, key=k, mod=0, unicode="", scancode=0))
    pygame.event.post(pygame.event.Event(pygame.KEYUP, key=k, mod=0, unicode="", scancode=0))


def frames(app, n):
    app.run(app.frames + n)


@pytest.fixture
def app():
    a = make_app()
    yield a
    a.close()


def record_calls(obj, method, calls):
    """Wrap ``obj.method`` so that every call's arguments are appended to ``calls``."""
    original = getattr(obj, method)

    def wrapper(*args, **kwargs):
        calls.append(args)
        return original(*args, **kwargs)

    setattr(obj, method, wrapper)


def test_every_robot_and_each_filters_belief_of_each_robot_are_drawn(app):
    frames(app, 60)  # 1 s: 20 ticks
    robots, calls, tags = [], [], []
    record_calls(app.renderer, "robot", robots)
    record_calls(app.renderer, "_ellipses", calls)
    record_calls(app.renderer, "name_tag", tags)
    app.smooth = False  # the world drawn afresh now (the loop keeps its picture between ticks)
    app.draw()
    s = app.session
    poses = s.poses
    # each true robot once, at its true pose
    assert len(robots) == 3
    for (_, _, pose, _), truth in zip(robots, poses, strict=True):
        assert np.array_equal(pose, truth)
    # each filter's 95 % ellipse of each robot, at that filter's estimate of it (drawn in
    # its colour, or in stripes with the filters whose ellipse lies on it)
    ellipses = [e for c in calls for e in c[2]]
    assert len(ellipses) == len(FILTERS) * 3
    for name in FILTERS:
        means, covs = s.estimates(name)
        mine = [e for e in ellipses if e[0] == name]
        assert len(mine) == 3, name
        for i in range(3):
            assert any(np.array_equal(e[1], means[i]) and np.array_equal(e[2], covs[i]) for e in mine)
    # each robot's name on its tag; only the driven one (scout) marked
    assert [(t[4], t[5]) for t in tags] == [("scout", True), ("relay", False), ("explorer", False)]
    # and on the screen: each filter's colour near the explorer, whose beliefs differ (on
    # the scout, ci's belief is the independent one's exactly: stripes), and each
    # robot's ring in the robot colour
    pix = pygame.surfarray.pixels3d(app.screen)
    try:
        for i in range(3):
            cx, cy = (ipx(v) for v in app.view.to_px(poses[i][:2]))
            patch = pix[cx - 30:cx + 31, cy - 30:cy + 31].reshape(-1, 3)
            for name in FILTERS if i == 2 else ():
                assert (patch == np.array(app.colours[name])).all(axis=1).any(), (name, i)
            assert (patch == np.array(palette.ROBOT)).all(axis=1).any(), i
            # the driven robot sits on the yellow halo, the others do not
            halo = (patch == np.array(palette.DRIVEN)).all(axis=1).any()
            assert halo == (i == 0)
    finally:
        del pix


def test_robot_readings_are_drawn_as_dashed_lines_apart_from_beacon_readings(app):
    frames(app, 60)
    s = app.session
    assert any(s.robot_readings(i) for i in range(3)), "team_sparse: robots see each other at 1 s"
    rays, robot_rays = [], []
    record_calls(app.renderer, "rays", rays)
    record_calls(app.renderer, "robot_rays", robot_rays)
    app.smooth = False  # the world drawn afresh now (the loop keeps its picture between ticks)
    app.draw()
    assert [list(c[4]) for c in rays] == [s.beacon_readings(i) for i in range(3)]
    assert [list(c[4]) for c in robot_rays] == [s.robot_readings(i) for i in range(3)]
    assert all(m.kind.startswith("robot_") for c in robot_rays for m in c[4])
    assert palette.ROBOT_RAY != palette.RAY


def test_tab_switches_the_driven_robot_and_w_drives_it_while_the_others_follow_drivers(app):
    s = app.session
    used = []  # the controls given to TeamSimulation.step on each tick
    step = s.sim.step

    def spy(controls=None):
        used.append(dict(controls or {}))
        return step(controls)

    s.sim.step = spy
    frames(app, 30)
    assert s.driven == 0 and s.driven_name == "scout"
    key(pygame.K_TAB)
    frames(app, 1)
    assert s.driven == 1 and s.driven_name == "relay"
    assert "relay" in app.banner_text  # the window says who is driven now
    # the keys take over the relay's last command (it was following its waypoints), rounded
    # to the keyboard's steps (no fractional omega left curving the robot)
    last = s.last_step.steps[1].control
    lim = s.keyboard.limits
    assert s.keyboard.control.v == pytest.approx(round(last.v / lim.v_step) * lim.v_step) != 0
    assert s.keyboard.control.omega == pytest.approx(round(last.omega / lim.omega_step) * lim.omega_step)
    key(pygame.K_x)
    frames(app, 1)
    start = s.poses[1].copy()
    for _ in range(3):
        key(pygame.K_w)
    frames(app, 120)  # 2 s
    assert s.keyboard.control == Control(0.3, 0.0)
    assert s.last_step.steps[1].control == Control(0.3, 0.0)
    # the relay went about 0.6 m along its heading (1.57 rad: up)
    moved = s.poses[1][:2] - start[:2]
    assert 0.4 < moved[1] < 0.8 and abs(moved[0]) < 0.2
    # the scout, no longer driven, follows its waypoints again (0.3 m/s)
    assert s.last_step.steps[0].control.v == pytest.approx(0.3, abs=0.01)
    # every tick drove exactly one robot by the keys: the scout before Tab, the relay after
    assert {tuple(c) for c in used} == {(0,), (1,)}
    assert [tuple(c) for c in used].index((1,)) > 0
    # the same controls fed to a headless TeamSimulation give the same truth, bit for bit
    sim = TeamSimulation(s.team, s.seed)
    for c in used:
        sim.step(c)
    assert sim.truth_checksum == s.sim.truth_checksum
    assert np.array_equal(sim.poses, s.poses)
    key(pygame.K_TAB)
    key(pygame.K_TAB)
    frames(app, 1)
    assert s.driven == 0  # round the team and back


def run_keys(frame_s: float, seconds: float = 4.0) -> tuple[str, np.ndarray]:
    """A team window whose frames each last ``frame_s``; the same keys at the same
    simulated moments (Tab at 0.5 s, W W at 1 s, A at 2 s, K at 3 s)."""
    a = make_app()
    try:
        script = {0.5: [pygame.K_TAB], 1.0: [pygame.K_w, pygame.K_w], 2.0: [pygame.K_a],
                  3.0: [pygame.K_k]}
        for n in range(round(seconds / frame_s)):
            for when in [w for w in script if abs(w - n * frame_s) < 1e-6]:
                for k in script.pop(when):
                    key(k)
            a.frame(frame_s)
        assert not script  # every key was pressed
        return a.session.sim.truth_checksum, a.session.poses
    finally:
        a.close()


def test_the_same_keys_give_the_same_truth_whatever_the_frame_rate():
    c60, p60 = run_keys(1 / 60)
    again, p_again = run_keys(1 / 60)
    assert np.array_equal(p60, p_again)
    c20, p20 = run_keys(1 / 20)
    assert c60 == again == c20
    assert np.array_equal(p60, p20)
    # and the keys did something: the kidnap at 3 s moved the relay (driven after Tab)
    quiet = make_app()
    try:
        for _ in range(240):
            quiet.frame(1 / 60)
        assert quiet.session.sim.truth_checksum != c60
        assert np.array_equal(quiet.session.poses[2], p60[2])  # the explorer never driven
        assert not np.array_equal(quiet.session.poses[1], p60[1])
    finally:
        quiet.close()


class BrokenTeamFilter:
    """A team filter whose predict raises (a student's bug)."""

    def __init__(self, ctx):
        self.n = len(ctx.members)

    def reset(self, beliefs):
        self.beliefs = list(beliefs)

    def predict(self, controls, dt):
        raise ZeroDivisionError("my predict divides by zero")

    def update(self, measurements):
        pass

    def estimates(self):
        return [(b.mean, b.cov) for b in self.beliefs]


def test_a_failing_team_filter_is_switched_off_with_its_message_and_the_others_go_on(monkeypatch):
    from beacon_sim.filters import team

    monkeypatch.setitem(team.TEAM_FILTERS, "broken", BrokenTeamFilter)
    a = make_app(["centralised", "broken"])
    try:
        notes = []
        record_calls(a.hud, "notes", notes)
        frames(a, 60)
        s = a.session
        assert "ZeroDivisionError" in s.status["broken"].failed
        assert "my predict divides by zero" in s.status["broken"].failed
        assert not s.status["centralised"].failed
        assert s.filters_run.track("centralised").ticks[-1] == s.sim.tick == 20
        shown = [t for call in notes for t in call[4] if t]
        assert any(t.startswith("broken switched off:") and "divides by zero" in t for t in shown)
        # the broken filter's belief is no longer drawn; the centralised one's still is
        ellipses = []
        record_calls(a.renderer, "uncertainty", ellipses)
        frames(a, 1)
        assert {c[4] for c in ellipses} == {a.colours["centralised"]}
    finally:
        a.close()


def test_memory_is_bounded_and_filters_can_be_hidden_and_reset(app):
    s = app.session
    frames(app, 600)  # 10 s: 200 ticks
    for tr in s.runner.tracks.values():
        assert len(tr.means) <= KEEP_ESTIMATES
    assert s.sim.tick == 200
    key(pygame.K_2)  # hide the centralised filter
    ellipses = []
    record_calls(app.renderer, "uncertainty", ellipses)
    frames(app, 1)
    assert not s.visible["centralised"]
    assert app.colours["centralised"] not in {c[4] for c in ellipses}
    key(pygame.K_r)  # every team filter back to the initial beliefs on the next tick
    frames(app, 3)
    assert not any(st.failed for st in s.status.values())


def test_help_lists_tab_and_only_the_team_keys(app):
    app.help = True
    frames(app, 1)
    keys = [k for k, _ in app.hud.help_drawn]
    assert "Tab" in keys and "W / Up" in keys and "K" in keys
    assert "P" not in keys and "B" not in keys  # particles, bound: single-robot only


def test_cli_play_opens_the_team_window_and_saves_a_screenshot(tmp_path, capsys, monkeypatch):
    from beacon_sim.cli.main import main

    monkeypatch.chdir(tmp_path)  # play records to ./recordings: never into the checkout

    out = tmp_path / "team.png"
    assert main(["play", "team_sparse", "--autopilot", "--frames", "30", "--screenshot",
                 str(out)]) == 0
    assert pygame.image.load(str(out)).get_size() == (1280, 800)
    out2 = tmp_path / "team2.png"
    path = Path(__file__).resolve().parents[2] / "scenarios" / "team" / "team_sparse.toml"
    assert main(["play", str(path), "--filter", "centralised",
                 "--frames", "3", "--screenshot", str(out2)]) == 0
    assert out2.exists()
    assert main(["play", "team_sparse", "--filter", "ekf", "--frames", "1"]) == 2
    assert "no team filter named 'ekf'" in capsys.readouterr().err
    # the same specs and --set checks as run: a bad parameter is a usage error, not a window
    assert main(["play", "team_sparse", "--filter", "centralised", "--set", "centralised.nosuch=1",
                 "--frames", "1"]) == 2
    assert "unknown parameter 'nosuch'" in capsys.readouterr().err
    # every robot's own single-robot filter (a student's too) in the window
    out3 = tmp_path / "team3.png"
    assert main(["play", "team_sparse", "--filter", "independent:ukf", "--filter", "centralised",
                 "--frames", "3", "--screenshot", str(out3)]) == 0
    assert out3.exists()
