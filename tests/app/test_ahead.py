"""What the window computes ahead on the filters' worker (app/ahead.py): the live bound read
as of the tick shown, and the drawing's costly pieces kept by the numbers they come from, so
that a new pose or a new reading is never drawn with an old result."""

from __future__ import annotations

import os
import threading

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import numpy as np

from beacon_sim.app import ahead, shapes
from beacon_sim.app.window import SCRIPTED_FRAME_S, App
from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.types import Measurement
from beacon_sim.evaluation.live_bound import LiveBound
from beacon_sim.runs.live import Session


def test_the_bound_is_read_as_of_the_tick_shown_while_the_worker_runs_ahead():
    sc = load_scenario("default")
    s = Session(sc, ["ekf"], 4)
    s.toggle_autopilot()
    app = App(s, (800, 600), scripted=True)
    try:
        for _ in range(5):
            s.tick()  # in the tick: fed when shown
        s.start_worker()
        for _ in range(6):
            app.frame(SCRIPTED_FRAME_S)
        for _ in range(4):  # the worker feeds these; none is shown yet
            s.tick()
        s.settle_worker()
        shown = s.tick_count
        assert s.sim.tick >= shown + 4  # the worker fed these, none is shown
        ref = LiveBound(sc)
        for step in s.steps[:shown]:
            ref.feed(step.steps[0])
        assert app.bound.valid and np.array_equal(app.bound.P, ref.P)
        assert app.bound.sigmas() == ref.sigmas()
        s.collect()
        for step in s.steps[shown:s.tick_count]:
            ref.feed(step.steps[0])
        assert np.array_equal(app.bound.P, ref.P)  # now the newest
    finally:
        app.close()


def test_kept_pieces_follow_the_pose_and_the_reading():
    sc = load_scenario("office")
    grid = sc.world.grid
    spec = next(sp for sp in sc.sensors if np.isfinite(sp.max_range))
    a = np.array([2.0, 2.0, 0.3])
    b = np.array([2.5, 2.0, 0.3])
    out_a = ahead.sensor_outline(a, spec, grid)
    assert np.array_equal(out_a, shapes.sensor_outline(a, spec.fov, spec.max_range, grid))
    out_b = ahead.sensor_outline(b, spec, grid)
    assert np.array_equal(out_b, shapes.sensor_outline(b, spec.fov, spec.max_range, grid))
    assert not np.array_equal(out_a, out_b)
    angles = np.linspace(-1.0, 1.0, 9)
    m1 = Measurement("scan", "scan", np.stack([np.full(9, 3.0), angles], 1), np.zeros(9, dtype=int))
    m2 = Measurement("scan", "scan", np.stack([np.full(9, 3.0), angles + 0.5], 1), np.zeros(9, dtype=int))
    w1 = ahead.scan_walls(grid, a, m1, 8.0)
    w2 = ahead.scan_walls(grid, a, m2, 8.0)  # another reading at the same pose: its own walls
    assert not np.array_equal(w1, w2)
    assert ahead.scan_walls(grid, b, m1, 8.0) is not w1


def test_the_worker_computes_the_drawings_pieces_and_the_drawing_finds_them(monkeypatch):
    where: list[int] = []
    real = shapes.sensor_outline

    def counted(*args, **kw):
        where.append(threading.get_ident())
        return real(*args, **kw)

    monkeypatch.setattr(shapes, "sensor_outline", counted)
    s = Session(load_scenario("office"), ["mcl"], 2)
    s.toggle_autopilot()
    app = App(s, (800, 600), scripted=True)
    app.smooth = True
    try:
        s.start_worker()
        app.lockstep = True
        app.frame(SCRIPTED_FRAME_S)  # tick 0, drawn before any tick reached the worker
        where.clear()
        for _ in range(40):
            app.frame(SCRIPTED_FRAME_S)
        main = threading.get_ident()
        assert s.tick_count >= 5 and len(where) >= 5
        assert main not in where  # every outline drawn since was computed on the worker
    finally:
        app.close()
