"""The window with its filters on a worker thread (``App.filter_thread``): the same pictures and
the same recording as with the filters in each tick; keys land on the same ticks; while the
worker is behind the window runs no new tick (none skipped: the simulation slows down) and
keeps drawing; closing stops the worker and writes the recording's end."""

from __future__ import annotations

import datetime
import os
import textwrap
import threading
import time
import types

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import numpy as np
import pygame
import pytest

from beacon_sim.app.window import SCRIPTED_FRAME_S, App
from beacon_sim.core.scenario import load_scenario
from beacon_sim.io.recording import load_recording
from beacon_sim.runs import recorder as recorder_mod
from beacon_sim.runs.live import Session
from beacon_sim.runs.recorder import Recorder

FILTERS = ["ekf", "pf", "histogram"]
PARAMS = {"pf": {"n_particles": 400}}


class _FixedClock:
    @staticmethod
    def now(tz=None):
        return datetime.datetime(2026, 1, 2, 3, 4, 5, tzinfo=datetime.UTC)


@pytest.fixture
def fixed_created(monkeypatch):
    monkeypatch.setattr(recorder_mod, "_dt", types.SimpleNamespace(datetime=_FixedClock))


def key(app: App, name: str) -> None:
    code = getattr(pygame, f"K_{name}")
    pygame.event.post(pygame.event.Event(pygame.KEYDOWN, key=code, mod=0, unicode=name, scancode=0))
    pygame.event.post(pygame.event.Event(pygame.KEYUP, key=code, mod=0, unicode=name, scancode=0))


def session_run(tmp_path, threaded: bool, size=(1024, 768)) -> tuple[App, list[np.ndarray], bytes]:
    """120 scripted frames with keys (drive, kidnap, reset, pause and a step), the screen
    after some of them, the recording's bytes."""
    sc = load_scenario("default")
    path = tmp_path / f"window_{threaded}.jsonl"
    s = Session(sc, FILTERS, 9, PARAMS, Recorder(path, sc, 9, FILTERS, PARAMS))
    app = App(s, size, scripted=True)
    app.filter_thread, app.lockstep = threaded, True
    shots = []
    try:
        keys = {5: "w", 10: "w", 20: "a", 40: "k", 55: "r", 70: "d", 80: "SPACE", 90: "PERIOD",
                95: "PERIOD", 100: "SPACE"}
        for frame in range(120):
            if frame in keys:
                key(app, keys[frame].lower() if len(keys[frame]) == 1 else keys[frame])
            app.run(app.frames + 1)
            if frame % 15 == 7:
                shots.append(pygame.surfarray.array3d(app.screen).copy())
    finally:
        app.close()
    return app, shots, path.read_bytes()


def test_the_threaded_window_draws_and_records_what_the_synchronous_one_does(tmp_path, fixed_created,
                                                                              monkeypatch):
    from beacon_sim.app import window

    monkeypatch.setattr(window, "fps_of", lambda times: 60.0)  # the panel's FPS: wall time
    sync_app, sync_shots, sync_rec = session_run(tmp_path, threaded=False)
    thr_app, thr_shots, thr_rec = session_run(tmp_path, threaded=True)
    assert thr_rec == sync_rec
    assert sync_app.session.tick_count == thr_app.session.tick_count > 20
    for a, b in zip(sync_shots, thr_shots, strict=True):
        assert np.array_equal(a, b)
    assert thr_app.session.worker is None  # run() stopped it


SLOW = textwrap.dedent('''
    import time
    from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter

    class Slow(ExtendedKalmanFilter):
        """An EKF whose update computes for 60 ms of CPU time: slower than real time (the
        worker's slow warning counts its thread's CPU time, not a wait)."""
        def update(self, measurements):
            t = time.thread_time()
            while time.thread_time() - t < 0.06:
                pass
            super().update(measurements)
''')


def test_a_worker_behind_slows_the_simulation_down_and_skips_no_tick(tmp_path):
    path = tmp_path / "slow.py"
    path.write_text(SLOW)
    sc = load_scenario("default")
    rec = tmp_path / "slow.jsonl"
    specs = [f"{path}:Slow", "ekf"]
    s = Session(sc, specs, 2, {}, Recorder(rec, sc, 2, specs, {}))
    s.toggle_autopilot()
    app = App(s, (800, 600), scripted=True)
    app.filter_thread = True
    app.clock.set_speed(8.0)  # 8 x 1/60 s a frame: 2-3 ticks a frame asked, 60 ms each
    behind = 0
    try:
        s.start_worker()  # as run() does on a real (not scripted) window
        for _ in range(90):
            app.frame(SCRIPTED_FRAME_S)
            time.sleep(SCRIPTED_FRAME_S)  # frames a sixtieth of a second apart, as on screen
            behind += s.filters_behind
            # the picture is of one tick: the shown truth is that tick's
            assert s.tick_count <= s.sim.tick
            if s.last_step is not None:
                assert s.last_step.tick == s.tick_count
                assert np.array_equal(s.true_pose, s.last_step.steps[0].true_pose)
        assert behind > 0
        asked = 90 * 8 * SCRIPTED_FRAME_S / sc.dt
        assert s.sim.tick < asked  # slower than asked: the worker set the pace
        worker = s.worker
        assert worker is not None
    finally:
        app.close()
    assert not worker.alive and s.worker is None
    recording = load_recording(rec)
    ticks = [t.tick for t in recording.ticks]
    assert ticks == list(range(1, len(ticks) + 1)) and len(ticks) == s.sim.tick
    assert recording.end is not None
    assert len(s.runner.tracks["Slow"].ticks) == s.sim.tick  # every tick fed, none skipped
    assert s.status["Slow"].failed is None  # slow is not a failure (the panel warns)
    assert "slow" in (s.status["Slow"].warning or "")


def test_closing_the_window_stops_the_worker_and_ends_the_recording(tmp_path):
    sc = load_scenario("default")
    rec = tmp_path / "close.jsonl"
    s = Session(sc, ["ekf"], 1, {}, Recorder(rec, sc, 1, ["ekf"], {}))
    s.toggle_autopilot()
    app = App(s, (640, 480), scripted=True)
    app.filter_thread = True
    app.run(1)
    assert s.worker is None  # run() ends with the filters in each tick again
    s.start_worker()  # still running when the window closes (as after a signal)
    for _ in range(30):
        app.frame(SCRIPTED_FRAME_S)
    worker = s.worker
    assert worker is not None and worker.alive
    app.close()
    assert not worker.alive
    assert not any(t.name == "beacon-sim filters" for t in threading.enumerate())
    recording = load_recording(rec)
    assert recording.end is not None and len(recording.ticks) == s.sim.tick > 0

