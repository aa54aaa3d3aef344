"""A single robot is a team of one: the team-of-one scenario, simulation and
runner give the single-robot run bit for bit, and a team's ``independent:F`` run through
:class:`TeamRunner` equals the joint ``IndependentTeam`` form."""

from __future__ import annotations

import numpy as np
import pytest

from beacon_sim.core.scenario import (
    as_team,
    load_any_scenario,
    load_scenario,
    load_team_scenario,
    team_of_one,
)
from beacon_sim.core.simulation import Simulation
from beacon_sim.core.team import TeamSimulation
from beacon_sim.hosting.loading import build_filters
from beacon_sim.hosting.runner import FilterRunner
from beacon_sim.hosting.team_runner import JointRunner, TeamRunner
from beacon_sim.hosting.team_specs import build_team_spec


@pytest.mark.parametrize("name", ["krejsa_bearing_only", "default"])
def test_team_of_one_is_the_single_robot_run(name):
    sc = load_scenario(name)
    team = team_of_one(sc)
    assert team.solo and team.n_robots == 1 and team.robots[0].scenario is sc
    assert as_team(sc).robots[0].scenario is sc and as_team(team) is team
    assert load_any_scenario(name).robots[0].scenario == sc
    specs = ["ekf", "pf", "dead_reckoning"]
    sim, tsim = Simulation(sc, 7), TeamSimulation(team, 7)
    built, _ = build_filters(specs, sc, 7)
    single = FilterRunner(built)
    tr = TeamRunner(team, specs, 7)
    assert tr.names == list(built) and tr.members[0].tracks.keys() == single.tracks.keys()
    for _ in range(120):
        s, ts = sim.step(), tsim.step()
        assert np.array_equal(s.true_pose, ts.steps[0].true_pose)
        single.feed(s)
        tr.feed(ts)
    assert sim.truth_checksum == tsim.sims[0].truth_checksum
    for n in tr.names:
        a, b = single.tracks[n], tr.track(n)
        assert np.array_equal(np.array(a.means), np.array(b.means))
        assert np.array_equal(np.array(a.covs), np.array(b.covs))
        ticks, means, covs = tr.series(n)
        assert means.shape == (120, 1, 3) and np.array_equal(means[:, 0], np.array(a.means))
        assert np.array_equal(covs[:, 0], np.array(a.covs)) and list(ticks) == list(a.ticks)


def test_independent_member_copies_equal_the_joint_independent_team():
    team = load_team_scenario("team_sparse")
    spec = "independent:ukf"
    runner = TeamRunner(team, [spec, "centralised"], 5)
    joint = JointRunner({spec: build_team_spec(spec, team, None, 5)}, team.n_robots)
    assert runner.is_member(spec) and not runner.is_member("centralised")
    sim = TeamSimulation(team, 5)
    for _ in range(60):
        step = sim.step()
        runner.feed(step)
        joint.feed(step.tick, step.time, [s.control for s in step.steps], step.dt,
                   [step.measurements(i) for i in range(len(step.steps))])
    _, means, covs = runner.series(spec)
    assert means.shape == (60, team.n_robots, 3)
    assert np.array_equal(means, np.array(joint.tracks[spec].means))
    assert np.array_equal(covs, np.array(joint.tracks[spec].covs))
    assert runner.latest("centralised")[0].shape == (team.n_robots, 3)
    assert runner.failed(spec) is None and runner.failed("centralised") is None


def test_a_copy_failing_on_one_robot_switches_the_filter_off_on_all(tmp_path):
    team = load_team_scenario("team_sparse")
    f = tmp_path / "flaky.py"
    f.write_text(
        "from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter\n"
        "class Flaky(ExtendedKalmanFilter):\n"
        "    def update(self, ms):\n"
        "        if self.ctx.name.endswith('/2'):\n"
        "            raise RuntimeError('robot two breaks')\n"
        "        super().update(ms)\n")
    spec = f"independent:{f}:Flaky"
    runner = TeamRunner(team, [spec], 5)
    sim = TeamSimulation(team, 5)
    for _ in range(5):
        runner.feed(sim.step())
    why = runner.failed(spec)
    assert why is not None and "robot two breaks" in why
    assert all(r.tracks[spec].failed for r in runner.members)


def test_the_single_robot_session_is_the_team_session_with_one_robot():
    from beacon_sim.runs.live import Session

    sc = load_scenario("default")
    single = Session(sc, ["ekf", "dead_reckoning"], seed=4)
    team = Session(load_team_scenario("team_sparse"), ["independent:ekf", "ci"], seed=4)
    assert type(single) is type(team) is Session
    assert single.n_robots == 1 and single.team.solo and single.scenario is sc
    assert team.n_robots == team.team.n_robots > 1 and not team.team.solo
    sim = Simulation(sc, 4)
    built, _ = build_filters(["ekf", "dead_reckoning"], sc, 4)
    ref = FilterRunner(built)
    for _ in range(50):
        control = single.next_control()
        step = single.tick()
        ref.feed(sim.step(control))
        team.tick()
        assert np.array_equal(step.steps[0].true_pose, sim.pose)
    est = single.estimate("ekf")
    assert est is not None and np.array_equal(est[0], ref.tracks["ekf"].means[-1])
    assert team.estimates("ci")[0].shape == (team.n_robots, 3)
