"""The headless floor: one headless run over N robots. A single-robot run is the
N-robot run with N = 1 (the same class), and its figures are those of a plain single-robot
loop (Simulation + FilterRunner, written out here as ``run`` computed them before), key by
key; the wall-clock timings aside."""

from __future__ import annotations

import json

import numpy as np
import pytest

from beacon_sim.core.metrics import summary
from beacon_sim.core.scenario import load_scenario, load_team_scenario, team_of_one
from beacon_sim.core.simulation import Simulation
from beacon_sim.hosting.loading import build_filters
from beacon_sim.hosting.runner import HEADLESS_STEP_LIMIT_S, FilterRunner
from beacon_sim.runs.headless import ACCURACY_KEYS, RunResult, run_headless

#: Wall-clock figures: they differ from run to run.
TIMING_KEYS = ("steps_per_s", "us_per_step")

FLAKY = ("from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter\n"
         "class Flaky(ExtendedKalmanFilter):\n"
         "    def update(self, ms):\n"
         "        self.n = getattr(self, 'n', 0) + 1\n"
         "        if self.n == 25:\n"
         "            raise RuntimeError('update 25 breaks')\n"
         "        super().update(ms)\n")


def plain_single_run(scenario, specs, seed, duration):
    """A single-robot run the plain way: one Simulation, one FilterRunner, the figures as
    ``run --json`` has always printed them."""
    built, broken = build_filters(specs, scenario, seed)
    runner = FilterRunner(built, step_limit_s=HEADLESS_STEP_LIMIT_S)
    for name, (message, tb) in broken.items():
        runner.tracks[name].failed, runner.tracks[name].traceback = message, tb
    sim = Simulation(scenario, seed)
    steps = []
    for _ in range(round(duration / scenario.dt)):
        steps.append(sim.step())
        runner.feed(steps[-1])
    distance, prev = 0.0, np.array(scenario.initial_pose)
    for s in steps:
        if not s.kidnapped:
            distance += float(np.hypot(*(s.true_pose[:2] - prev[:2])))
        prev = s.true_pose
    counts = {s.name: 0 for s in scenario.sensors}
    for s in steps:
        for m in s.measurements:
            counts[m.sensor] += len(m)
    truth_by_tick = {s.tick: s.true_pose for s in steps}
    filters = {}
    for name, tr in runner.tracks.items():
        row = {}
        if tr.failed:
            row.update(dict.fromkeys(ACCURACY_KEYS))
            row.update(failed=tr.failed, failed_time_s=tr.failed_time_s)
        elif tr.means:
            row.update(summary(np.array(tr.means), np.array(tr.covs),
                               np.array([truth_by_tick[t] for t in tr.ticks])))
        if tr.slow_warning:
            row["slow_warning"] = tr.slow_warning
        filters[name] = row
    return {"scenario": scenario.name, "seed": seed, "steps": len(steps),
            "sim_time_s": round(len(steps) * scenario.dt, 9), "distance_m": distance,
            "measurements": counts,
            "events": [{"kind": e.kind, "tick": e.tick, "time": e.time, "detail": e.detail}
                       for s in steps for e in s.events],
            "truth_checksum": sim.truth_checksum, "filters": filters}, runner


def without_timings(d):
    out = {k: v for k, v in d.items() if k not in TIMING_KEYS}
    out["filters"] = {n: {k: v for k, v in r.items() if k not in TIMING_KEYS}
                      for n, r in d["filters"].items()}
    return out


@pytest.mark.parametrize("name, duration", [("default", 15.0), ("sparse_kidnap", 30.0)])
@pytest.mark.parametrize("seed", [3, 11])
def test_a_single_robot_run_is_the_plain_single_robot_run_key_by_key(name, duration, seed, tmp_path):
    sc = load_scenario(name)
    (tmp_path / "flaky.py").write_text(FLAKY)
    specs = ["ekf", "dead_reckoning", "ukf", f"{tmp_path / 'flaky.py'}:Flaky"]
    want, runner = plain_single_run(sc, specs, seed, duration)
    res = run_headless(sc, specs, seed=seed, duration=duration)
    got = without_timings(res.as_json())
    assert list(got) == [k for k in res.as_json() if k not in TIMING_KEYS]
    assert got.keys() == want.keys()
    for key in want:
        assert got[key] == want[key], key  # the same floats, bit for bit
    assert "update 25 breaks" in got["filters"]["Flaky"]["failed"]
    assert all(k in res.as_json()["filters"][n] for n in res.names for k in TIMING_KEYS[1:])
    for n, tr in runner.tracks.items():  # the robot-0 views are the single robot's
        assert np.array_equal(np.array(res.runner.tracks[n].means), np.array(tr.means))
    assert [s.true_pose.tolist() for s in res.steps] == [s.true_pose.tolist()
                                                         for s in res.robot_steps(0)]
    assert res.scenario is sc and res.truth.shape == (round(duration / sc.dt), 3)


def test_the_single_robot_run_is_the_n_robot_run_with_n_1():
    sc = load_scenario("default")
    solo = run_headless(sc, ["ekf"], seed=2, duration=2.0)
    team = run_headless(load_team_scenario("team_sparse"), ["centralised", "independent:ekf"],
                        seed=2, duration=2.0)
    assert type(solo) is type(team) is RunResult
    assert solo.n_robots == 1 and solo.team.solo and team.n_robots == 3 and not team.team.solo
    T, T3 = round(2.0 / sc.dt), round(2.0 / team.team.dt)
    assert solo.true_poses.shape == (T, 1, 3) and team.true_poses.shape == (T3, 3, 3)
    again = run_headless(team_of_one(sc), ["ekf"], seed=2, duration=2.0)  # a team of one, given as one
    assert without_timings(again.as_json()) == without_timings(solo.as_json())
    ticks, means, covs = solo.filters.series("ekf")
    assert means.shape == (T, 1, 3) and covs.shape == (T, 1, 3, 3) and ticks[0] == 1
    # a single-robot filter on every robot of a team and a team filter, in one run
    assert team.filters.is_member("independent:ekf") and not team.filters.is_member("centralised")
    d = team.as_json()  # a team's output keeps its keys
    assert set(d) == {"scenario", "team", "seed", "steps", "sim_time_s", "robots", "anees_band",
                      "team_anees_band", "readings", "truth_checksum", "filters"}
    for name in ("centralised", "independent:ekf"):
        assert set(d["filters"][name]) == {"robots", "team_pos_rmse_m", "team_heading_rmse_rad",
                                           "team_anees", "team_anees_verdict", "us_per_step"}
        assert set(d["filters"][name]["robots"]) == {r.name for r in team.team.robots}
        assert d["filters"][name]["team_pos_rmse_m"] > 0


def test_run_json_on_the_command_line_is_the_plain_single_robot_run(capsys):
    from beacon_sim.cli.main import main

    assert main(["run", "krejsa_bearing_only", "--duration", "10", "--seed", "5", "--json"]) == 0
    got = without_timings(json.loads(capsys.readouterr().out))
    sc = load_scenario("krejsa_bearing_only")
    want, _ = plain_single_run(sc, list(sc.default_filters), 5, 10.0)
    assert got == json.loads(json.dumps(want, default=float))
