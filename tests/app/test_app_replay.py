"""Replay on screen (SDL dummy driver): the window driven by a recording reproduces the
recorded truth, seeking backward then forward lands on the same state as a straight run,
and ``beacon-sim replay FILE --frames N --screenshot PNG`` works."""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import numpy as np
import pygame
from replay_app_helpers import FILTERS, TICKS, key, make, run_until  # noqa: F401

from beacon_sim.app import controls
from beacon_sim.app.loop import SPEEDS
from beacon_sim.app.replay import ReplayApp
from beacon_sim.cli.main import main
from beacon_sim.io.recording import load_recording
from beacon_sim.runs.replay import ReplaySession


def test_replay_on_screen_reproduces_the_recorded_truth_and_estimates(recorded, capsys):
    path, live = recorded
    app = make(path)
    try:
        app.clock.speed_index = SPEEDS.index(8.0)
        run_until(app, TICKS)
        app.run(app.frames + 5)                       # past the end: nothing more happens
        s = app.session
        assert s.sim.tick == TICKS and s.mismatch is None
        assert s.sim.truth_checksum == live["checksum"] == load_recording(path).end["checksum"]
        np.testing.assert_array_equal(s.true_pose, live["pose"])
        np.testing.assert_array_equal(s.runner.tracks["ekf"].means[-1], live["ekf"])
        assert "verified" in app.banner_text
        assert "truth checksum verified" in capsys.readouterr().err
    finally:
        app.close()


def test_seeking_back_then_forward_lands_on_the_straight_run_state(recorded):
    path, _ = recorded
    straight = make(path)
    try:
        run_until(straight, 160)                      # x1: one tick every 3 frames, exact
        assert straight.session.sim.tick == 160
        ref = straight.session
        ref_pose, ref_sum = ref.true_pose.copy(), ref.sim.truth_checksum
        ref_ekf = ref.runner.tracks["ekf"].means[-1].copy()
        ref_trail = ref.truth_trail.points[: ref.truth_trail.n].copy()
    finally:
        straight.close()

    app = make(path)
    try:
        key(pygame.K_SPACE)                           # pause: only seeks move time
        for _ in range(3):
            key(pygame.K_RIGHT)                       # +5 s each: tick 300
        app.run(app.frames + 1)
        assert app.session.sim.tick == 300
        first = app.session.sim
        key(pygame.K_LEFT)                            # back to 200: re-simulated from 0
        key(pygame.K_LEFT)
        app.run(app.frames + 1)
        assert app.session.sim.tick == 100 and app.session.sim is not first
        bar = app._bar_rect()                         # click the timeline at 0.5 = tick 160
        at = (bar.left + bar.width * 0.5, bar.centery)
        pygame.event.post(pygame.event.Event(pygame.MOUSEBUTTONDOWN, pos=at, button=1))
        pygame.event.post(pygame.event.Event(pygame.MOUSEBUTTONUP, pos=at, button=1))
        app.run(app.frames + 1)
        s = app.session
        assert s.sim.tick == 160
        np.testing.assert_array_equal(s.true_pose, ref_pose)
        assert s.sim.truth_checksum == ref_sum
        np.testing.assert_array_equal(s.runner.tracks["ekf"].means[-1], ref_ekf)
        np.testing.assert_array_equal(s.truth_trail.points[: s.truth_trail.n], ref_trail)
        key(pygame.K_PERIOD)                          # one step while paused
        app.run(app.frames + 1)
        assert app.session.sim.tick == 161
    finally:
        app.close()


def test_help_in_replay_lists_the_timeline_keys_and_no_driving(recorded):
    path, _ = recorded
    app = make(path)
    try:
        key(pygame.K_h)
        app.run(app.frames + 1)
        drawn = app.hud.help_drawn
        assert drawn == [(b.keys, b.description) for b in controls.bindings("replay")]
        keys = {k for k, _ in drawn}
        assert {"Left", "Right", "Click timeline", "Space", ".", "+", "-"} <= keys
        assert not {"W / Up", "K", "R", "Left click"} & keys
        key(pygame.K_w)                               # driving keys do nothing in a replay
        key(pygame.K_k)
        app.run(app.frames + 30)
        assert not app.session.pending and not app.session.commands
    finally:
        app.close()


def test_cli_replay_on_screen_writes_a_screenshot(recorded, tmp_path):
    path, _ = recorded
    png = tmp_path / "replay.png"
    assert main(["replay", str(path), "--frames", "20", "--screenshot", str(png)]) == 0
    img = pygame.image.load(str(png))
    assert img.get_size() == (1280, 800)
    # The timeline strip is the panel colour with the dark position marker in it.
    assert img.get_at((5, 790))[:3] == (255, 255, 255)


def test_mrclam_on_screen_shows_the_truth_and_the_estimates_at_the_tick(tmp_path, capsys):
    """The MRCLAM view (a synthetic folder in the real format, from test_mrclam): at a
    display tick, the robot is the interpolated ground truth and each filter's estimate
    is its latest one at or before that time."""
    from mrclam_helpers import make_folder

    from beacon_sim.io.mrclam import load_mrclam
    from beacon_sim.runs.mrclam import MrclamPlayback, run_mrclam

    folder = tmp_path / "Synthetic"
    make_folder(folder, seconds=30.0)
    run = run_mrclam(load_mrclam(folder, 1), ["ekf", "dead_reckoning"])
    app = ReplayApp(MrclamPlayback(run), size=(960, 600), scripted=True)
    try:
        app.clock.speed_index = SPEEDS.index(8.0)
        app.run(20)
        s = app.session
        assert s.tick_count > 0
        t = run.t_start + s.tick_count * run.scenario.dt
        truth, _ = run.data.truth_at(np.array([t]))
        np.testing.assert_allclose(s.true_pose, truth[0])
        ekf = run.tracks["ekf"]
        i = int(np.searchsorted(ekf.times, t, side="right")) - 1
        assert ekf.times[i] <= t < (ekf.times[i + 1] if i + 1 < len(ekf.times) else np.inf)
        np.testing.assert_array_equal(s.estimate("ekf")[0], ekf.means[i])
        key(pygame.K_SPACE)
        key(pygame.K_LEFT)                            # paused, seek back: clamped at 0
        app.run(app.frames + 1)
        assert s.tick_count == 0 and len(s.truth_trail.pieces()) == 0
        app.seek(s.total_ticks)
        app.run(app.frames + 2)
        assert s.at_end
        png = tmp_path / "mrclam.png"
        app.save_screenshot(png)
        assert png.stat().st_size > 10_000
    finally:
        app.close()


def test_an_old_recording_whose_readings_differ_shows_not_verified(tmp_path, capsys):
    """A recording made before the portable maths (it does not name its maths) whose
    readings differ here plays on, under a "NOT VERIFIED" banner that says why (not an edit),
    and the window exits 0."""
    from pathlib import Path

    from beacon_sim.app import palette

    old = Path(__file__).parents[1] / "data" / "old_recordings" / "v3_sparse_kidnap.jsonl"
    rec = load_recording(old)
    app = ReplayApp(ReplaySession(rec, ["ekf", "dead_reckoning"]), size=(960, 600), scripted=True)
    try:
        run_until(app, 30)
        assert app.session.mismatch is None and app.session.sim.tick >= 30
        assert app.session.unverified.startswith("not verified: made before beacon-sim's portable")
        x, y, w, h = app.view.area
        strip = pygame.surfarray.pixels3d(app.screen)[x:x + w, y + h - 60:y + h - 12]
        assert int(np.all(strip == palette.BANNER_BG, axis=-1).sum()) > 2000
        del strip
    finally:
        app.close()
    assert main(["replay", str(old), "--frames", "90"]) == 0
    assert "checksum not verified: made before beacon-sim's portable maths" in capsys.readouterr().err
