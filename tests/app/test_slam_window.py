"""The window draws each SLAM filter's estimated map: its landmarks' 95 % ellipses in the
filter's colour beside the true beacons; a ``landmarks()`` that returns garbage or raises
switches that filter off with the reason and the window goes on."""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import numpy as np
import pygame

from beacon_sim.app.map_layer import ELLIPSE_95, checked_map
from beacon_sim.app.window import App
from beacon_sim.core.geometry import covariance_ellipse
from beacon_sim.core.scenario import load_scenario
from beacon_sim.filters.base import LandmarkMap
from beacon_sim.runs.live import Session


def _app(filters):
    return App(Session(load_scenario("slam_loop"), list(filters), 3), (1280, 800), scripted=True)


def test_the_map_is_drawn_as_95_percent_ellipses_in_the_filters_colour():
    app = _app(["ekf_slam"])
    for _ in range(15):
        app.session.tick()
    app.draw()
    flt = app.session.filters["ekf_slam"]
    lm = flt.landmarks()
    assert len(lm.means) >= 1
    colour = pygame.Color(*app.colours["ekf_slam"])
    hits = total = 0
    for mean, cov in zip(lm.means, lm.covs, strict=True):
        for x, y in app.view.to_px(covariance_ellipse(mean, cov, ELLIPSE_95, 24)):
            total += 1
            near = [app.screen.get_at((int(x) + dx, int(y) + dy)) for dx in (-1, 0, 1) for dy in (-1, 0, 1)]
            hits += colour in near
    assert hits > 0.8 * total, (hits, total)
    # Without the map the same pixels are not the filter's colour: the layer drew them.
    app.show.ellipses = False
    app.draw()
    mean, cov = lm.means[0], lm.covs[0]
    x, y = app.view.to_px(covariance_ellipse(mean, cov, ELLIPSE_95, 24))[0]
    assert app.screen.get_at((int(x), int(y))) != colour


class _BadMap:
    def __init__(self, how):
        self.how = how

    def __call__(self):
        if self.how == "raise":
            raise RuntimeError("no map today")
        return LandmarkMap(None, np.array([[np.nan, 0.0]]), np.eye(2)[None])


def test_a_broken_landmarks_switches_the_filter_off_and_the_window_goes_on():
    for how, words in (("raise", "RuntimeError: no map today"), ("nan", "not a finite number")):
        app = _app(["ekf_slam", "fastslam"])
        app.session.tick()
        app.session.filters["ekf_slam"].landmarks = _BadMap(how)
        app.draw()
        assert words in (app.session.status["ekf_slam"].failed or "")
        assert app.session.status["fastslam"].failed is None
        app.session.tick()
        app.draw()


def test_checked_map_shapes():
    ok = checked_map(LandmarkMap(np.array([1]), np.zeros((1, 2)), np.eye(2)[None]))
    assert isinstance(ok, LandmarkMap) and ok.means.shape == (1, 2)
    assert "means but" in checked_map(LandmarkMap(None, np.zeros((2, 2)), np.eye(2)[None]))
    assert "expected a LandmarkMap" in checked_map(object())


def test_the_batched_ellipses_are_the_geometry_modules():
    from beacon_sim.app.map_layer import ellipses

    rng = np.random.default_rng(4)
    A = rng.normal(size=(5, 2, 2))
    covs = A @ A.transpose(0, 2, 1)
    means = rng.normal(size=(5, 2))
    got = ellipses(means, covs, 24)
    for k in range(5):
        ref = covariance_ellipse(means[k], covs[k], ELLIPSE_95, 24)
        # the same curve (eigenvector signs may differ: compare as point sets)
        d = np.min(np.linalg.norm(got[k][:, None] - ref[None], axis=2), axis=1)
        assert np.all(d < 1e-9 * (1 + np.abs(ref).max()) + 1e-9)
