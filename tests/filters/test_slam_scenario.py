"""The scenario side of SLAM: ``[model] map = "unknown"`` withholds the beacons from the
filters' context (anchors kept), one-line errors for bad keys, the shipped SLAM scenario is
listed and runs headless with both SLAM filters, and a localization filter on it is switched
off with a message instead of breaking the run."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from slam_helpers import ring_scenario

from beacon_sim.core.resources import shipped_scenarios
from beacon_sim.core.scenario import ScenarioError, load_scenario, parse_scenario
from beacon_sim.hosting.loading import build_filter
from beacon_sim.runs.headless import run_headless


def _data(**model):
    sc = ring_scenario(4)
    data = {"world": {"bounds": list(sc.world.bounds),
                      "beacons": [{"id": b.id, "x": b.x, "y": b.y} for b in sc.world.beacons]},
            "robot": {"initial_pose": list(sc.initial_pose)},
            "sensors": [{"name": "beacons", "kind": "range_bearing"}]}
    if model:
        data["model"] = model
    return data


def test_the_map_is_known_unless_the_scenario_says_otherwise():
    sc = parse_scenario(_data(), "x.toml")
    assert sc.map_known and sc.filter_world is sc.world
    flt = build_filter("ekf", sc, 0)
    assert flt.ctx.map_known and len(flt.ctx.world.beacons) == 4


def test_an_unknown_map_withholds_every_beacon_but_the_anchors():
    data = _data(map="unknown")
    data["world"]["beacons"][2]["anchor"] = True
    sc = parse_scenario(data, "x.toml")
    assert not sc.map_known and sc.anchor_ids == (3,)
    f = build_filter("ekf_slam", sc, 0)
    assert not f.ctx.map_known and [b.id for b in f.ctx.world.beacons] == [3]
    assert f.ctx.world.bounds == sc.world.bounds and len(sc.world.beacons) == 4  # the truth keeps all


@pytest.mark.parametrize("change, message", [
    (lambda d: d.setdefault("model", {}).update(map="secret"), "model.map = 'secret': expected one of"),
    (lambda d: d["world"]["beacons"][0].update(anchor=True), "world.beacons[0].anchor = true: an anchor"),
    (lambda d: d["world"]["beacons"][0].update(anchor=1), "beacons[0].anchor = 1: expected true or false"),
    (lambda d: d.setdefault("model", {}).update(mapp="unknown"), "did you mean 'model.map'"),
])
def test_bad_map_keys_are_one_line_errors(change, message):
    data = copy.deepcopy(_data())
    change(data)
    with pytest.raises(ScenarioError) as e:
        parse_scenario(data, "x.toml")
    assert message in str(e.value) and "\n" not in str(e.value)


def test_the_slam_scenario_ships_and_both_filters_close_the_loop():
    assert "slam_loop" in shipped_scenarios()
    sc = load_scenario("slam_loop")
    assert not sc.map_known and sc.filter_world.beacons == ()
    res = run_headless(sc, ["ekf_slam", "fastslam", "ekf"], duration=sc.duration)
    truth = np.array([s.true_pose for s in res.steps])
    for name in ("ekf_slam", "fastslam"):
        track = res.runner.tracks[name]
        assert track.failed is None, track.failed
        flt = track.filter
        lm = flt.landmarks()
        assert sorted(lm.ids.tolist()) == [b.id for b in sc.world.beacons]
        est = flt.estimate()[0]
        assert np.hypot(*(est[:2] - truth[-1, :2])) < 0.3, name
    assert "not on the map" in (res.runner.tracks["ekf"].failed or "")


def test_the_loop_closure_shrinks_the_whole_map_at_once():
    """EKF-SLAM on slam_loop: from 60 s (coming back, the first beacons not yet in view again)
    to 75 s (after seeing them), the summed 95 % ellipse areas of the landmarks not in view at
    75 s shrink by more than half, and so does the pose's."""
    from beacon_sim.core.sensors import visible_beacons
    from beacon_sim.core.simulation import Simulation

    sc = load_scenario("slam_loop")
    f = build_filter("ekf_slam", sc, sc.seed)
    sim = Simulation(sc, sc.seed)
    snap = {}
    for _ in range(round(76.0 / sc.dt)):
        st = sim.step()
        f.predict(st.control, st.dt)
        f.update(st.measurements)
        if round(st.time / sc.dt) in (round(60.0 / sc.dt), round(75.0 / sc.dt)):
            lm = f.landmarks()
            snap[round(st.time)] = ({int(i): float(np.sqrt(np.linalg.det(c))) for i, c in zip(lm.ids, lm.covs,
                                                                                         strict=True)},
                                    float(np.sqrt(np.linalg.det(f.estimate()[1][:2, :2]))), st.true_pose)
    (before, pose_before, _), (after, pose_after, pose75) = snap[60], snap[75]
    in_view = set(sc.world.beacon_ids[visible_beacons(sc.sensors[0], pose75, sc.world)].tolist())
    far = [i for i in before if i not in in_view]
    assert len(far) >= 5
    assert sum(after[i] for i in far) < 0.5 * sum(before[i] for i in far)
    assert pose_after < 0.5 * pose_before


def test_a_localization_filter_on_an_unknown_map_gets_a_note_first():
    from beacon_sim.hosting.loading import sensor_note

    sc = load_scenario("slam_loop")
    note = sensor_note("pf", sc)
    assert note is not None and "has no landmarks()" in note and "\n" not in note
    assert sensor_note("ekf_slam", sc) is None and sensor_note("dead_reckoning", sc) is None
    assert sensor_note("pf", load_scenario("default")) is None
