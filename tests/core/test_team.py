"""Several robots that see each other (core/team*.py, filters/team.py, runs/headless.py)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from beacon_sim.core.metrics import anees_band
from beacon_sim.core.scenario import ScenarioError, load_scenario, load_team_scenario, parse_team_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.core.team import TeamSimulation
from beacon_sim.core.team_models import (
    relative_range_bearing,
    relative_range_bearing_jacobians,
    relative_rows,
    teammate_position,
)
from beacon_sim.runs.headless import run_headless


@pytest.mark.parametrize("pi, pj", [([1.0, 2.0, 0.3], [4.0, -1.0, 2.0]),
                                    ([-2.0, 0.5, -3.0], [-2.5, 3.0, 0.1]),
                                    ([0.0, 0.0, 3.1], [-1.0, 0.01, -3.1])])
def test_robot_to_robot_jacobians_match_finite_differences(pi, pj):
    pi, pj = np.array(pi), np.array(pj)
    hi, hj = relative_range_bearing_jacobians(pi, pj)

    def wrap_rows(d):
        d = d.copy()
        d[1] = (d[1] + np.pi) % (2 * np.pi) - np.pi
        return d

    for which, H in ((0, hi), (1, hj)):
        num = np.zeros((2, 3))
        for k in range(3):
            e = np.zeros(3)
            e[k] = 1e-6
            a = [pi + e, pj] if which == 0 else [pi, pj + e]
            b = [pi - e, pj] if which == 0 else [pi, pj - e]
            num[:, k] = wrap_rows(relative_range_bearing(*a) - relative_range_bearing(*b)) / 2e-6
        np.testing.assert_allclose(H, num, atol=1e-6)
    h, Hi, Hj = relative_rows("robot_bearing", pi, pj)
    assert h.shape == (1,) and np.allclose(Hi, hi[1:]) and np.allclose(Hj, hj[1:])


def test_teammate_position_jacobians_match_finite_differences():
    pose, z = np.array([1.0, -2.0, 0.7]), np.array([2.5, -1.1])
    p, jx, jz = teammate_position(pose, z)
    rb = relative_range_bearing(pose, p)
    np.testing.assert_allclose(rb, z, atol=1e-12)  # consistent with the measurement model
    for arg, J in ((0, jx), (1, jz)):
        base = [pose, z]
        num = np.zeros_like(J)
        for k in range(J.shape[1]):
            a, b = [v.copy() for v in base], [v.copy() for v in base]
            a[arg][k] += 1e-6
            b[arg][k] -= 1e-6
            num[:, k] = (teammate_position(*a)[0] - teammate_position(*b)[0]) / 2e-6
        np.testing.assert_allclose(J, num, atol=1e-6)


@pytest.fixture(scope="module")
def team():
    return load_team_scenario("team_sparse")


def test_team_simulation_is_reproducible_and_robot_sensors_do_not_change_the_truth(team):
    a = TeamSimulation(team, 3)
    a.run(5.0)
    b = TeamSimulation(team, 3)
    b.run(5.0)
    assert a.truth_checksum == b.truth_checksum
    blind = team.with_changes(robots=tuple(dataclasses.replace(r, robot_sensors=())
                                           for r in team.robots))
    c = TeamSimulation(blind, 3)
    c.run(5.0)
    assert c.truth_checksum == a.truth_checksum
    d = TeamSimulation(team, 4)
    d.run(5.0)
    assert d.truth_checksum != a.truth_checksum


def test_single_robot_scenarios_are_untouched():
    """A single-robot file still loads as before and rejects [[robots]]; its truth is the
    Simulation's, which the team code does not change."""
    sc = load_scenario("default")
    sim = Simulation(sc)
    sim.run(2.0)
    sim2 = Simulation(sc)
    sim2.run(2.0)
    assert sim.truth_checksum == sim2.truth_checksum
    with pytest.raises(ScenarioError, match="robots"):
        from beacon_sim.core.scenario import parse_scenario
        parse_scenario({"world": {"bounds": [0, 0, 1, 1]}, "robot": {"initial_pose": [0.5, 0.5, 0]},
                        "robots": []}, "x.toml")


def test_team_file_errors_name_the_robot(team):
    base = {"dt": 0.1, "world": {"bounds": [0, 0, 5, 5], "beacons": [{"id": 1, "x": 1, "y": 1}]}}
    good = {"initial_pose": [1, 1, 0], "sensors": [{"kind": "robot_range_bearing", "max_range": 3.0}]}
    sc = parse_team_scenario({**base, "robots": [good, {**good, "initial_pose": [2, 2, 0]}]}, "t.toml")
    assert sc.ids == (1, 2) and sc.robots[0].robot_sensors[0].max_range == 3.0
    with pytest.raises(ScenarioError, match=r"robots\[1\]\.initial_pose"):
        parse_team_scenario({**base, "robots": [good, {**good, "initial_pose": [9, 9, 0]}]}, "t.toml")
    with pytest.raises(ScenarioError, match=r"robots\[1\]\.id"):
        parse_team_scenario({**base, "robots": [{**good, "id": 4}, {**good, "id": 4}]}, "t.toml")
    with pytest.raises(ScenarioError, match=r"robots\[0\]\.sensors\[0\]\.kind"):
        parse_team_scenario({**base, "robots": [{"initial_pose": [1, 1, 0],
                                                 "sensors": [{"kind": "robot_lidar"}]}]}, "t.toml")
    with pytest.raises(ScenarioError, match=r"robots\[0\]\.sensors\[1\]\.max_rnage"):
        parse_team_scenario({**base, "robots": [{"initial_pose": [1, 1, 0], "sensors": [
            {"kind": "range_bearing"}, {"kind": "range_bearing", "name": "b", "max_rnage": 1}]}]}, "t.toml")


def test_centralised_equals_independent_without_robot_readings(team):
    blind = team.with_changes(robots=tuple(dataclasses.replace(r, robot_sensors=(), model_robot_sensors=())
                                           for r in team.robots))
    r = run_headless(blind, ["independent", "centralised", "decentralised"], seed=2, duration=20.0)
    a = r.tracks["independent"]
    for name in ("centralised", "decentralised"):
        b = r.tracks[name]
        np.testing.assert_allclose(np.array(a.means), np.array(b.means), rtol=0, atol=1e-9)
        np.testing.assert_allclose(np.array(a.covs), np.array(b.covs), rtol=0, atol=1e-10)
    # ... and with robot readings they differ (the test can fail)
    r2 = run_headless(team, ["independent", "centralised"], seed=2, duration=20.0)
    gap = np.array(r2.tracks["independent"].means) - np.array(r2.tracks["centralised"].means)
    assert np.abs(gap).max() > 1e-3


SEEDS = (11, 12, 13, 14)


@pytest.fixture(scope="module")
def runs(team):
    return [run_headless(team, ["independent", "centralised", "decentralised", "ci", "naive"],
                         seed=s, duration=40.0)
            for s in SEEDS]


def test_decentralised_filters_are_consistent_where_naive_fusion_is_overconfident(runs, team):
    """ANEES over the seeded runs, per robot: the pairwise decentralised filter inside the
    95 % band (for len(SEEDS) independent runs), CI at or below its upper edge (CI may be
    conservative), the naive fusion that double-counts far above it."""
    lo, hi = anees_band(len(SEEDS))
    naive = []
    for i, robot in enumerate(team.robots):
        dec = np.mean([np.mean(r.nees("decentralised", i)) for r in runs])
        ci = np.mean([np.mean(r.nees("ci", i)) for r in runs])
        naive.append(np.mean([np.mean(r.nees("naive", i)) for r in runs]))
        assert lo <= dec <= hi, (robot.name, dec, lo, hi)
        assert ci <= hi, (robot.name, ci, hi)
    assert np.mean(naive) > 2 * hi, (naive, hi)  # the team's ANEES under naive fusion
    assert max(naive[1:]) > 2 * hi  # the relay and the explorer exchange the most


def test_team_sparse_cooperation_localizes_the_robot_without_beacons(runs, team):
    i = [r.name for r in team.robots].index("explorer")
    assert all(r.readings()[i]["beacon"] == 0 for r in runs)  # it never sees a beacon
    alone = np.mean([r.robot_summary("independent", i)["pos_rmse_m"] for r in runs])
    for name in ("centralised", "decentralised", "ci"):
        coop = np.mean([r.robot_summary(name, i)["pos_rmse_m"] for r in runs])
        assert coop < 0.6 * alone, (name, coop, alone)
    # the centralised filter is consistent for every robot
    hi = anees_band(len(SEEDS))[1]
    lo = anees_band(len(SEEDS))[0]
    for k in range(len(team.robots)):
        a = np.mean([np.mean(r.nees("centralised", k)) for r in runs])
        assert lo <= a <= hi, (k, a)


def test_decentralised_factors_keep_the_joint_covariance_valid(team):
    """The joint covariance the pairwise factors imply (S_ij = s_ij s_ji^T) stays symmetric
    positive definite through a run with many robot readings, and its cross-covariances are
    not all zero (the factors carry the correlation the robot readings create)."""
    from beacon_sim.core.team import TeamSimulation
    from beacon_sim.filters.team import build_team_filter

    f = build_team_filter("decentralised", team, seed=4)
    sim = TeamSimulation(team, 4)
    cross = 0.0
    for _ in range(400):
        st = sim.step()
        f.predict([s.control for s in st.steps], st.dt)
        f.update([st.measurements(i) for i in range(len(team.robots))])
        _, P = f.joint()
        assert np.allclose(P, P.T, atol=1e-12)
        assert np.linalg.eigvalsh(P).min() > 0
        cross = max(cross, float(np.abs(P[:3, 3:]).max()))
    assert cross > 1e-4
