"""The classroom demonstration: in ``default`` and ``assignment_kf`` every
Gaussian filter's 95 % ellipse grows to several robot widths in the blind stretch and falls
back to a few centimetres once three beacons are in view, and the window shows it (nothing
covers an ellipse, not even the true robot)."""

from __future__ import annotations

import os
from pathlib import Path

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import numpy as np
import pygame
import pytest

from beacon_sim.app.estimate_layer import ELLIPSE_SCALE2
from beacon_sim.app.window import App
from beacon_sim.core.geometry import covariance_ellipse
from beacon_sim.core.scenario import load_scenario
from beacon_sim.runs.headless import run_headless
from beacon_sim.runs.live import Session

#: Semi-major axis [m] of the 95 % ellipse the blind stretch must reach (robot radius 0.2 m).
BLIND_A95 = 0.5
#: ... reached within this many seconds of losing the last beacon [s].
BLIND_WITHIN_S = 10.0
#: Semi-major axis [m] it must be back under, ...
SEEN_A95 = 0.1
#: ... this many seconds after three beacons come into view [s].
SEEN_AFTER_S = 2.0


def a95(cov) -> float:
    """Semi-major axis [m] of the 95 % ellipse of the x-y block of ``cov``."""
    return float(np.sqrt(ELLIPSE_SCALE2 * np.linalg.eigvalsh(np.asarray(cov)[:2, :2]).max()))


def beacons_in_view(steps, scenario) -> np.ndarray:
    """Per step, how many beacons the sensor's latest reading used (held between readings)."""
    every = round(scenario.sensors[0].period / scenario.dt)
    out, last = [], 0
    for s in steps:
        if s.tick % every == 0:
            last = len({int(i) for m in s.measurements for i in m.beacon_ids})
        out.append(last)
    return np.array(out)


def demo_moments(steps, scenario) -> tuple[int, int, int]:
    """(first, end) step index of the longest blind stretch, and the first step after it
    with three beacons in view."""
    n = beacons_in_view(steps, scenario)
    blind = np.concatenate([[0], (n == 0).astype(int), [0]])
    edges = np.flatnonzero(np.diff(blind))
    starts, ends = edges[::2], edges[1::2]
    k = int(np.argmax(ends - starts))
    b0, b1 = int(starts[k]), int(ends[k])
    three = b1 + int(np.argmax(n[b1:] >= 3))
    assert n[three] >= 3, "the tour never sees three beacons after the blind stretch"
    return b0, b1, three


CASES = [("assignment_kf", ["kf", "ekf", "ukf"]), ("default", ["ekf", "ukf"])]


@pytest.mark.parametrize(("scenario", "filters"), CASES)
def test_the_ellipse_grows_blind_and_collapses_with_three_beacons(scenario, filters):
    sc = load_scenario(scenario)
    r = run_headless(sc, filters)
    b0, b1, three = demo_moments(r.steps, sc)
    k10 = min(b0 + round(BLIND_WITHIN_S / sc.dt), b1)
    k2 = three + round(SEEN_AFTER_S / sc.dt)
    for name, tr in r.runner.tracks.items():
        assert not tr.failed, tr.failed
        assert tr.ticks == [s.tick for s in r.steps]
        peak = max(a95(c) for c in tr.covs[b0:k10 + 1])
        seen = a95(tr.covs[k2])
        assert peak >= BLIND_A95, f"{scenario} {name}: blind 95 % ellipse only {peak:.3f} m"
        assert seen <= SEEN_A95, f"{scenario} {name}: with three beacons still {seen:.3f} m"


def ellipse_pixels_shown(app: App, name: str) -> tuple[int, int, int]:
    """How many points of filter ``name``'s drawn 95 % ellipse are outside the true robot's
    body, how many of those show the filter's colour, and how many inside show it.

    The ellipse is computed from the estimate the window drew; a point counts as shown
    when its colour is within 2 px of it (line width)."""
    mean, cov = app.session.estimate(name)
    pts = app.view.to_px(covariance_ellipse(mean[:2], cov[:2, :2], ELLIPSE_SCALE2, 180))
    centre = app.view.to_px(app.session.true_pose[:2])
    body_px = app.session.scenario.robot_radius * app.view.scale
    colour = pygame.Color(*app.colours[name])
    surf = app.screen
    outside = shown_out = shown_in = 0
    for x, y in pts:
        hit = any(surf.get_at((int(x) + dx, int(y) + dy)) == colour
                  for dx in (-2, -1, 0, 1, 2) for dy in (-2, -1, 0, 1, 2))
        if np.hypot(x - centre[0], y - centre[1]) > body_px + 3:
            outside += 1
            shown_out += hit
        else:
            shown_in += hit
    return outside, shown_out, shown_in


def test_the_blind_ellipse_shows_outside_the_robot_and_the_small_one_over_it():
    sc = load_scenario("assignment_kf")
    steps = run_headless(sc, []).steps
    b0, _, three = demo_moments(steps, sc)
    app = App(Session(sc, ["kf"]), (1600, 1000), scripted=True)
    try:
        app.session.toggle_autopilot()
        app.show.trails = False
        for _ in range(b0 + round(BLIND_WITHIN_S / sc.dt)):
            app.session.tick()
        app.draw()
        outside, shown, _ = ellipse_pixels_shown(app, "kf")
        assert outside > 90, "the blind ellipse is not larger than the robot"
        assert shown >= 0.9 * outside, f"only {shown} of {outside} ellipse points visible"
        for _ in range(three + round(SEEN_AFTER_S / sc.dt) - app.session.tick_count):
            app.session.tick()
        app.draw()
        outside, _, shown_in = ellipse_pixels_shown(app, "kf")
        assert outside == 0  # a few centimetres: inside the robot's outline ...
        assert shown_in >= 0.9 * 180, f"only {shown_in} of 180 points visible over the robot"
    finally:
        app.close()


def test_the_strip_chart_toggles_and_draws_error_and_two_sigma():
    sc = load_scenario("assignment_kf")
    app = App(Session(sc, ["kf", "dead_reckoning"]), (1280, 800), scripted=True)
    try:
        app.session.toggle_autopilot()
        full = app.view.area
        app.act("chart")
        assert app.chart_rect is not None and app.view.area[3] < full[3]
        for _ in range(round(15.0 / sc.dt)):  # into the blind stretch
            app.session.tick()
            app.chart.record(app.session)
        app.draw()
        assert app.session.status["kf"].pos_sigma > 0.05
        w = app.chart.window()
        assert app.chart.blind[w].any() and not app.chart.blind[w].all()
        r = app.chart_rect
        img = pygame.surfarray.array3d(app.screen.subsurface(r))
        blue = np.all(img == np.array(app.colours["kf"]), axis=2)
        shade = np.all(img == np.array((255, 226, 204)), axis=2)
        assert blue.sum() > 200 and shade.sum() > 1000
        app.act("chart")
        assert app.chart_rect is None and app.view.area == full
    finally:
        app.close()


QUIET_DEFAULT = Path(__file__).resolve().parents[1] / "data" / "default_quiet.toml"


def test_the_bumper_stops_the_robot_at_the_wall_and_the_filters_follow():
    """Holding W drives straight into the wall at x = 12: the robot stops there, the
    filters are told v = 0, and none of them runs off (before the bumper: 14 m off)."""
    sc = load_scenario(QUIET_DEFAULT)
    s = Session(sc, ["ekf", "ukf", "pf", "dead_reckoning"])
    bumps = []
    for _ in range(round(30.0 / sc.dt)):
        s.keyboard.v = sc.keyboard.v_max  # W held
        step = s.tick().steps[0]
        bumps += [e for e in step.events if e.kind == "bump"]
        if [e for e in step.events if e.kind == "bump"]:
            assert step.control.v == 0.0
    assert bumps and s.true_pose[0] == pytest.approx(12.0, abs=0.3)
    for name in s.names:
        assert s.status[name].pos_err < 1.0, (name, s.status[name].pos_err)
    assert s.keyboard.v == 0.0  # the last tick bumped: the keyboard's command is zeroed


def test_the_bumper_leaves_a_run_that_never_touches_a_wall_alone():
    sc = load_scenario("krejsa_bearing_only")
    r = run_headless(sc, [], duration=20.0)
    assert not [e for s in r.steps for e in s.events if e.kind == "bump"]


def test_q_asks_before_quitting_and_backspace_clears_the_trails():
    sc = load_scenario("default")
    app = App(Session(sc, ["ekf"]), (1024, 768), scripted=True)
    try:
        app.session.toggle_autopilot()
        app.run(120)
        assert app.session.truth_trail.n > 2
        app.act("clear_trails")
        assert app.session.truth_trail.n == 1
        app.act("quit")
        assert app.running and "Quit?" in app.banner_text
        app.act("quit")
        assert not app.running
        assert app.view.area[2] > 0.65 * 1024  # at 1024x768 the room gets most of the width
    finally:
        app.close()


def test_without_a_display_play_says_so_in_one_line_and_exits_2(monkeypatch, capsys):
    from beacon_sim.cli.main import main

    monkeypatch.delenv("SDL_VIDEODRIVER", raising=False)
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr("sys.platform", "linux")
    assert main(["play", "default", "--no-record"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "display" in err[0]
