"""Every shipped scenario loads and runs; every broken file gives its message and exit 2."""

import subprocess
import sys
from pathlib import Path

import pytest

from beacon_sim.cli.main import main
from beacon_sim.core.resources import shipped_scenarios
from beacon_sim.core.scenario import ScenarioError, load_scenario
from beacon_sim.core.simulation import Simulation

BROKEN = Path(__file__).parents[1] / "data" / "broken"

# file -> fragments the one-line message must contain (besides the file's path).
EXPECTED = {
    "syntax_error.toml": ["not valid TOML"],
    "misspelt_key.toml": ["unknown key 'sensors[0].max_rnage'", "did you mean 'sensors[0].max_range'"],
    "negative_dt.toml": ["dt = -0.1", "expected a number in [0.001, 10]"],
    "short_pose.toml": ["robot.initial_pose = [1, 1]", "a list of 3"],
    "unknown_sensor_kind.toml": ["sensors[0].kind = 'lidar'", "one of 'bearing'"],
    "duplicate_beacon.toml": ["world.beacons[1].id = 1", "no other beacon has"],
    "kidnap_without_target.toml": ["events[0]", "exactly one of pose"],
    "probability_above_one.toml": ["sensors[0].detection_prob = 1.5", "in [0, 1]"],
    "pose_outside.toml": ["robot.initial_pose = [20.0, 1.0, 0.0]", "inside world.bounds"],
    "period_not_multiple.toml": ["sensors[0].period = 0.25", "whole multiple of dt"],
    "misspelt_table.toml": ["unknown key 'wrld'", "did you mean 'world'"],
    "misspelt_driver.toml": ["driver.kind = 'random_gaol'", "did you mean 'random_goal'"],
}


def test_every_broken_file_has_an_expectation():
    assert sorted(p.name for p in BROKEN.glob("*.toml")) == sorted(EXPECTED)


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_broken_file_message(name):
    path = BROKEN / name
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    msg = str(info.value)
    assert "\n" not in msg
    assert msg.startswith(str(path))
    for fragment in EXPECTED[name]:
        assert fragment in msg


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_cli_prints_one_line_and_exits_2(name, capsys):
    assert main(["run", str(BROKEN / name), "--filter", "dead_reckoning"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and EXPECTED[name][0] in err


def test_cli_subprocess_no_traceback():
    r = subprocess.run([sys.executable, "-m", "beacon_sim", "run", str(BROKEN / "misspelt_key.toml")],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr and r.stderr.strip().count("\n") == 0


def test_unknown_scenario_name_suggests_a_shipped_one():
    with pytest.raises(ScenarioError, match="did you mean 'default'"):
        load_scenario("defualt")


def test_missing_file():
    with pytest.raises(ScenarioError, match="no such scenario file"):
        load_scenario("nowhere/at_all.toml")


@pytest.mark.parametrize("name", ["default", "krejsa_bearing_only", "ulps_circle", "assignment_kf",
                                  "sparse_kidnap"])
def test_shipped_scenario_loads_and_runs(name):
    assert name in shipped_scenarios()
    sc = load_scenario(name)
    assert sc.name == name and sc.description
    steps = Simulation(sc).run(min(sc.duration, 30.0))
    assert sum(len(m) for s in steps for m in s.measurements) > 0


def test_shipped_scenarios_match_their_seeds():
    k = load_scenario("krejsa_bearing_only")
    assert len(k.world.beacons) == 4 and k.sensors[0].kind == "bearing"
    assert k.sensors[0].detection_prob == 0.5
    assert k.sensors[0].noise.bearing_std ** 2 == pytest.approx(3.141592653589793 / 8)
    assert k.events[0].offset == pytest.approx((1.0, 0.5, -3.141592653589793 / 2))
    assert k.driver.kind == "random_goal"
    u = load_scenario("ulps_circle")
    assert (u.driver.v, u.driver.omega) == pytest.approx((0.1, 3.141592653589793 / 100))
    assert u.dt == 0.2 and u.sensors[0].period == 0.2 and u.sensors[0].noise.position_std == 0.01
    assert u.motion_noise.v_frac == 0.25 and u.events[0].duration == 2.0
    a = load_scenario("assignment_kf")
    assert a.sensors[0].kind == "pose" and a.sensors[0].max_range < 5
    assert load_scenario("sparse_kidnap").initial_belief.global_
