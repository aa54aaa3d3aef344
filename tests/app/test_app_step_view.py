"""Predict and update, step by step: while paused the window draws each
Gaussian filter's ellipse after predict (the prior, dashed) and after update (the
posterior, solid) of the last tick, and the beacons the update used; B draws the best
achievable ellipse, the PCRB, computed live along the true path. ``--paused`` starts so."""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import numpy as np
import pygame
import pytest

from beacon_sim.app import controls
from beacon_sim.app.estimate_layer import ELLIPSE_SCALE2
from beacon_sim.app.view import ipx
from beacon_sim.app.window import SCRIPTED_FRAME_S, App
from beacon_sim.cli.main import main
from beacon_sim.core.geometry import covariance_ellipse
from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.evaluation.live_bound import LiveBound
from beacon_sim.evaluation.pcrb import pcrb
from beacon_sim.hosting.loading import build_filter
from beacon_sim.runs.live import Session


def blind_then_seen(filters=("kf", "dead_reckoning")):
    """assignment_kf on autopilot, paused on the first tick after the blind stretch whose
    update shrank the KF's ellipse (prior at least twice the posterior in size)."""
    sc = load_scenario("assignment_kf")
    s = Session(sc, list(filters), None)
    s.toggle_autopilot()
    app = App(s, (1280, 800), scripted=True)
    while s.time < 20.0:
        app.frame(SCRIPTED_FRAME_S)
    app.act("pause")
    while True:
        s.tick()
        pu = s.predict_update("kf")
        if s.used_ids() and pu is not None and \
                np.trace(pu[0][1][:2, :2]) > 4 * np.trace(pu[1][1][:2, :2]):
            return app, s, pu


def ellipse_px(app, mean, cov) -> np.ndarray:
    pts = app.view.to_px(covariance_ellipse(mean[:2], cov[:2, :2], ELLIPSE_SCALE2, 360))
    return np.array([(ipx(x), ipx(y)) for x, y in pts])


def hits(surf, pts, colour, tol=40) -> int:
    """How many of the points [px] have (about) ``colour`` within 1 px."""
    arr = pygame.surfarray.pixels3d(surf)
    h, w = arr.shape[1], arr.shape[0]
    n = 0
    for x, y in pts:
        box = arr[max(x - 1, 0): min(x + 2, w), max(y - 1, 0): min(y + 2, h)].reshape(-1, 3)
        n += bool(np.any(np.abs(box.astype(int) - colour).sum(axis=1) < tol))
    del arr
    return n


def test_prior_is_the_filter_after_predict_and_changes_nothing():
    app, s, ((m0, c0), (m1, _c1)) = blind_then_seen()
    try:
        # an independent KF, fed the same ticks but stopped after the last predict
        sc, k = s.scenario, s.tick_count
        f = build_filter("kf", sc, s.seed, name="kf")
        sim = Simulation(sc, s.seed)
        for i in range(k):
            step = sim.step(s.controls[i])
            f.predict(step.control, step.dt)
            if i < k - 1:
                f.update(step.measurements)
        mean, cov = f.estimate()
        np.testing.assert_array_equal(m0, mean)
        np.testing.assert_array_equal(c0, cov)
        f.update(step.measurements)
        np.testing.assert_array_equal(m1, f.estimate()[0])  # the posterior: unchanged results
        assert s.predict_update("dead_reckoning") is not None
    finally:
        app.close()


def test_step_view_draws_the_prior_dashed_apart_from_the_posterior():
    app, _s, ((m0, c0), (m1, c1)) = blind_then_seen()
    try:
        kf = app.colours["kf"]
        prior_px, post_px = ellipse_px(app, m0, c0), ellipse_px(app, m1, c1)
        app.draw()
        on = app.screen.copy()
        assert app.step_view()
        app.act("step_view")  # V: off
        assert not app.step_view()
        app.draw()
        off = app.screen.copy()
        on_hits, off_hits = hits(on, prior_px, kf), hits(off, prior_px, kf)
        assert on_hits > 3 * off_hits + 60, (on_hits, off_hits)  # (the trail crosses it)
        assert on_hits < 0.9 * len(prior_px)  # dashed: gaps along the prior
        assert not np.array_equal(pygame.surfarray.array3d(on), pygame.surfarray.array3d(off))
        assert set(map(tuple, prior_px)) != set(map(tuple, post_px))
        assert hits(on, post_px, kf) > 0.5 * len(post_px)  # the posterior: solid
        # running again hides the step view
        app.act("step_view")
        app.act("pause")
        assert not app.step_view()
    finally:
        app.close()


def test_bound_toggle_draws_the_pcrb_ellipse_around_the_truth():
    sc = load_scenario("assignment_kf")
    s = Session(sc, ["kf"], None)
    s.toggle_autopilot()
    app = App(s, (1280, 800), scripted=True)
    try:
        while s.time < 24.0:  # the blind stretch: the bound is broad too
            app.frame(SCRIPTED_FRAME_S)
        assert app.bound is not None and app.bound.valid
        pts = ellipse_px(app, s.true_pose, app.bound.P)
        app.draw()
        before = hits(app.screen, pts, (0, 0, 0), tol=60)
        key = controls.binding_for_key(pygame.K_b)
        assert key is not None and key.action == "bound"
        app.act("bound")
        app.draw()
        after = hits(app.screen, pts, (0, 0, 0), tol=60)
        assert after > before + 40, (before, after)
    finally:
        app.close()


def test_live_bound_equals_the_offline_pcrb():
    for name in ("default", "ulps_circle"):
        sc = load_scenario(name)
        steps = Simulation(sc, sc.seed).run(15.0)
        lb = LiveBound(sc)
        live = []
        for st in steps:
            lb.feed(st)
            live.append(lb.P.copy())
        truths = np.array([sc.initial_pose] + [st.true_pose for st in steps])[None]
        ctrl = np.array([[st.control.v, st.control.omega] for st in steps])[None]
        np.testing.assert_allclose(np.array(live), pcrb(sc, truths, ctrl)[0], rtol=1e-12,
                                   atol=1e-15)
        lb.feed(steps[5])  # not the next tick: no history, no bound
        assert not lb.valid


@pytest.mark.parametrize("paused", [True, False])
def test_paused_option_starts_paused(monkeypatch, paused):
    seen = {}
    real_close = App.close

    def close(self):
        seen.update(paused=self.clock.paused, ticks=self.session.tick_count)
        real_close(self)

    monkeypatch.setattr(App, "close", close)
    argv = ["play", "sparse_kidnap", "--frames", "30", "--no-record"]
    assert main([*argv, "--paused"] if paused else argv) == 0
    assert seen["paused"] is paused
    assert (seen["ticks"] == 0) is paused
