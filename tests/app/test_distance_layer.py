"""The window's distance layer: the curves through the robot (core/distance_curves.py) are
where the readings put it, and the window draws them, the fix's ellipse and the HDOP
shading with its key (app/distance_layer.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from beacon_sim.core.distance_curves import difference_curve, floor_hdop, range_circle
from beacon_sim.core.geometry import hdop
from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.trilateration import tdoa_hdop

REF, B = np.array([0.0, 0.0]), np.array([1.0, 0.3])


@pytest.mark.parametrize("h", [0.0, 3.45])
def test_every_point_of_a_difference_curve_has_that_difference(h):
    p = np.array([2.5, 1.7])
    r = lambda q, b: math.sqrt(float((q - b) @ (q - b)) + h * h)   # noqa: E731
    d = r(p, B) - r(p, REF)
    curve = difference_curve(REF, B, d, h, p + np.array([0.05, -0.03]), 6.0)
    assert curve is not None and len(curve) > 50
    assert max(abs(r(q, B) - r(q, REF) - d) for q in curve) < 1e-8
    assert min(np.hypot(*(curve - p).T)) < 0.1          # it passes by the robot
    steps = np.hypot(*np.diff(curve, axis=0).T)
    assert steps.max() < 0.2                            # a connected line, no jumps


def test_a_range_circle_is_the_floor_at_that_range():
    ring = range_circle(B, 5.0, 3.0)
    assert np.allclose(np.hypot(*(ring - B).T), 4.0)
    assert range_circle(B, 2.0, 3.0) is None            # shorter than the height: nowhere


def test_the_floor_hdop_is_each_kinds():
    bxy = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    xs, ys, val = floor_hdop("tdoa", (-2.0, -2.0, 3.0, 3.0), bxy, 3.45, 10, 8)
    assert val.shape == (8, 10)
    assert np.allclose(val[3, 4], tdoa_hdop(np.array([[xs[4], ys[3]]]), bxy, 3.45)[0])
    _, _, rv = floor_hdop("range", (-2.0, -2.0, 3.0, 3.0), bxy, 3.45, 10, 8)
    assert np.allclose(rv[3, 4], hdop(np.array([xs[4], ys[3]]), bxy, 3.45))
    assert np.all(val >= rv)                            # differences lose the common part


def test_the_window_draws_curves_fix_and_hdop_key(tmp_path, monkeypatch):
    import pygame

    from beacon_sim.app import ahead, distance_layer
    from beacon_sim.app.window import App
    from beacon_sim.runs.live import Session

    drawn = {"curves": 0, "fix": 0}
    real_fix = distance_layer._fix

    def fix(*a, **k):
        drawn["fix"] += 1
        return real_fix(*a, **k)

    real_curve = ahead.difference_curve  # the curves are traced there (ahead of the drawing)

    def curve(*a, **k):
        out = real_curve(*a, **k)
        drawn["curves"] += out is not None
        return out

    monkeypatch.setattr(distance_layer, "_fix", fix)
    monkeypatch.setattr(ahead, "difference_curve", curve)
    app = App(Session(load_scenario("ulps_leave"), ["ekf"], 3), (1000, 700), scripted=True)
    try:
        app.act_hdop()
        assert app.show.hdop
        app.run(app.frames + 40)
        edges = app.renderer.hdop_layer.edges
        assert len(edges) == 5 and edges[0] > 1.0 and list(edges) == sorted(edges)
        assert drawn["curves"] >= 3 and drawn["fix"] >= 1
        pygame.image.save(app.screen, str(tmp_path / "hdop.png"))
    finally:
        app.close()
    other = App(Session(load_scenario("default"), ["ekf"], 3), (800, 600), scripted=True)
    try:
        other.act_hdop()
        assert "no HDOP here" in other.banner_text
        other.run(other.frames + 3)
    finally:
        other.close()


@pytest.mark.parametrize("scenario", ["ulps_leave", "uwb_room", "ruiz_ulps"])
def test_the_gym_observation_holds_each_distance(scenario):
    import warnings

    from gymnasium.utils.env_checker import check_env

    from beacon_sim.gym import BeaconEnv, observation_names

    env = BeaconEnv(scenario, ["ekf"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        check_env(env, skip_render_check=True)
    obs, _ = env.reset(seed=4)
    for _ in range(3):
        obs, *_ = env.step(np.zeros(2, dtype=np.float32))
    names = observation_names(env.scenario)
    assert len(names) == obs.shape[0] == 3 * len(env.scenario.world.beacons)
    m = env.session.readings()[0]
    heard = obs[0::3]
    assert heard.sum() == len(m.beacon_ids) and np.all(obs[2::3] <= 1)
    if m.kind == "tdoa":
        ref = [b.id for b in env.scenario.world.beacons].index(int(m.beacon_ids[0]))
        assert obs[3 * ref + 2] == 1.0 and obs[3 * ref + 1] == 0.0 and obs[2::3].sum() == 1.0
        diffs = sorted(float(v) for v in obs[1::3] if v != 0.0)
        assert np.allclose(diffs, sorted(m.z[:, 0].astype(np.float32)))
    else:
        assert np.allclose(sorted(obs[1::3][heard > 0]), sorted(m.z[:, 0].astype(np.float32)))


@pytest.mark.parametrize("scenario", ["ruiz_ulps", "uwb_room"])
def test_a_played_session_records_and_replays_bit_for_bit(scenario, tmp_path, monkeypatch):
    """play records the distance readings' run; replay re-simulates it and checks the truth
    and readings checksums (a mismatch raises ReplayMismatch), then filters it afresh."""
    from beacon_sim import api
    from beacon_sim.cli.main import main

    monkeypatch.chdir(tmp_path)
    assert main(["play", scenario, "--frames", "90", "--autopilot", "--speed", "4",
                 "--filter", "ekf"]) == 0
    (rec,) = (tmp_path / "recordings").glob("*.jsonl")
    run = api.replay(rec, ["ekf", "pf"])
    kinds = set(run.readings["kind"].tolist())
    assert kinds == {"tdoa" if scenario == "ruiz_ulps" else "range"}
    met = run.metrics()["filters"]
    assert all(math.isfinite(met[n]["pos_rmse_m"]) for n in ("ekf", "pf"))
    again = api.replay(rec, ["ekf"])
    assert np.array_equal(again.estimates["ekf"], run.estimates["ekf"])
