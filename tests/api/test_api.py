"""The Python API (beacon_sim.__all__): the same runs and numbers as the command line, filter
classes as well as names, scenarios changed in code, plots that leave matplotlib alone."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import beacon_sim as bs
from beacon_sim.cli.main import main
from beacon_sim.core.scenario import ScenarioError

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
TIMING = ("steps_per_s", "us_per_step")  # wall-clock figures: the only ones allowed to differ


def _without_timing(data):
    if isinstance(data, dict):
        return {k: _without_timing(v) for k, v in data.items() if k not in TIMING}
    if isinstance(data, list):
        return [_without_timing(v) for v in data]
    return data


def test_public_names_resolve():
    for name in bs.__all__:
        assert getattr(bs, name) is not None
    with pytest.raises(AttributeError):
        bs.no_such_name  # noqa: B018


@pytest.mark.parametrize("scenario, seed", [("default", 5), ("sparse_kidnap", 2)])
def test_api_metrics_equal_run_json(scenario, seed, capsys):
    argv = ["run", scenario, "--filter", "ekf", "--filter", "pf", "--filter", "dead_reckoning",
            "--seed", str(seed), "--duration", "12", "--set", "pf.n_particles=300", "--json"]
    assert main(argv) == 0
    cli = json.loads(capsys.readouterr().out)
    r = bs.run(scenario, ["ekf", "pf", "dead_reckoning"], seed=seed, duration=12,
               params={"pf": {"n_particles": 300}})
    api = json.loads(json.dumps(r.metrics(), default=float))
    assert _without_timing(api) == _without_timing(cli)  # exact: every float, the checksum
    assert set(api["filters"]) == {"ekf", "pf", "dead_reckoning"}


def test_arrays_are_the_runs_own_numbers():
    r = bs.run("default", ["ekf", "dead_reckoning"], seed=1, duration=5)
    T = len(r.result.steps)
    assert r.truth.shape == (T + 1, 3) and r.time.shape == (T + 1,) and r.controls.shape == (T, 2)
    np.testing.assert_array_equal(r.truth[1:], [s.true_pose for s in r.result.steps])
    for name, track in r.result.runner.tracks.items():
        np.testing.assert_array_equal(r.estimates[name], np.array(track.means))
        np.testing.assert_array_equal(r.covariances[name], np.array(track.covs))
    n = sum(len(m) for s in r.result.steps for m in s.measurements)
    assert all(len(v) == n for v in r.readings.values())
    rmse = np.sqrt(np.mean(np.sum(r.errors("ekf")[:, :2] ** 2, axis=1)))
    assert rmse == pytest.approx(r.metrics()["filters"]["ekf"]["pos_rmse_m"], rel=1e-12)


def test_a_filter_class_runs_exactly_as_its_file_spec():
    sys.path.insert(0, str(EXAMPLES))
    try:
        from student_ekf import StudentEKF
    finally:
        sys.path.remove(str(EXAMPLES))
    by_class = bs.run("default", [StudentEKF, "ekf"], seed=4, duration=8)
    by_file = bs.run("default", [f"{EXAMPLES / 'student_ekf.py'}:StudentEKF", "ekf"], seed=4, duration=8)
    assert by_class.filter_names == by_file.filter_names == ["StudentEKF", "ekf"]
    np.testing.assert_array_equal(by_class.estimates["StudentEKF"], by_file.estimates["StudentEKF"])
    assert _without_timing(by_class.metrics()) == _without_timing(by_file.metrics())


def test_same_seed_same_run_bit_for_bit():
    a = bs.run("default", ["pf"], seed=9, duration=4, params={"pf": {"n_particles": 200}})
    b = bs.run("default", ["pf"], seed=9, duration=4, params={"pf": {"n_particles": 200}})
    np.testing.assert_array_equal(a.estimates["pf"], b.estimates["pf"])
    assert a.metrics()["truth_checksum"] == b.metrics()["truth_checksum"]


def test_scenario_changes_in_code_are_validated():
    sc = bs.load_scenario("default", {"duration": 7.5, "sensors.0.max_range": 5.0,
                                      "robot.motion_noise.v_frac": 0.1})
    assert (sc.duration, sc.sensors[0].max_range, sc.motion_noise.v_frac) == (7.5, 5.0, 0.1)
    with pytest.raises(ScenarioError, match="max_rnage"):
        bs.load_scenario("default", {"sensors.0.max_rnage": 5.0})
    with pytest.raises(ScenarioError, match="dt"):
        bs.load_scenario("default", {"dt": -1.0})


def test_plots_leave_matplotlibs_backend_and_pyplot_alone(tmp_path):
    """In a fresh interpreter with a chosen backend: every figure and PNG of the evaluation's
    plots, and the backend is still the chosen one, pyplot never imported, no figure open."""
    code = f"""
import sys, matplotlib
matplotlib.use("pdf")
before = (matplotlib.get_backend(), matplotlib.rcParams["backend"])
import beacon_sim as bs
from beacon_sim.evaluation import plots
r = bs.run("default", ["ekf"], seed=1, duration=3)
figs = [r.plot_trajectories(), r.plot_errors(), r.plot_nees()]
written = plots.plot_all(r.scenario, r.curves(), __import__("pathlib").Path({str(tmp_path)!r}), 1)
assert all(type(f).__name__ == "Figure" for f in figs), figs
assert len(written) == 4 and all(p.stat().st_size > 1000 for p in written)
assert (matplotlib.get_backend(), matplotlib.rcParams["backend"]) == before, before
assert "matplotlib.pyplot" not in sys.modules
print("ok")
"""
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stdout.strip() == "ok", r.stderr[-3000:]


def test_export_from_the_api(tmp_path):
    r = bs.run("default", ["ekf", "dead_reckoning"], seed=2, duration=3)
    (npz,) = r.export(tmp_path / "run.npz")
    with np.load(npz) as z:
        assert list(z["filter_names"]) == ["ekf", "dead_reckoning"]
        np.testing.assert_array_equal(z["est_mean"][0], r.estimates["ekf"])
        np.testing.assert_array_equal(z["truth"], r.truth)


def test_run_team_is_the_command_line_team_run(capsys):
    """bs.run_team equals ``beacon-sim run TEAM --json`` number for number, gives arrays per
    robot, and takes a team filter class defined in the notebook."""
    import json

    import numpy as np

    import beacon_sim as bs
    from beacon_sim.cli.main import main
    from beacon_sim.filters.team import IndependentTeam

    r = bs.run_team("team_sparse", ["centralised", "decentralised"], seed=2, duration=5)
    assert main(["run", "team_sparse", "--filter", "centralised", "--filter", "decentralised",
                 "--seed", "2", "--duration", "5", "--json"]) == 0
    cli = json.loads(capsys.readouterr().out)
    for name in ("centralised", "decentralised"):
        assert cli["filters"][name]["robots"] == r.metrics()["filters"][name]["robots"]
    assert r.robots == ["scout", "relay", "explorer"]
    assert r.truth.shape == (100, 3, 3) and r.estimates["centralised"].shape == (100, 3, 3)
    assert r.covariances["decentralised"].shape == (100, 3, 3, 3)
    assert np.abs(r.estimates["centralised"] - r.truth)[..., :2].max() < 0.5

    class Mine(IndependentTeam):  # a team filter class defined here, as in a notebook
        pass

    mine = bs.run_team("team_sparse", [Mine, "independent"], seed=2, duration=5)
    np.testing.assert_array_equal(mine.estimates["Mine"], mine.estimates["independent"])
    assert mine.failed("Mine") is None
