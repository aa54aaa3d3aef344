"""``beacon-sim replay``: the command line prints what ``run`` prints and checks the truth."""

from __future__ import annotations

import json

import pytest
from recording_helpers import SCENARIO, live_run

from beacon_sim.cli.main import main
from beacon_sim.core.scenario import load_scenario
from beacon_sim.runs.headless import run_headless
from beacon_sim.runs.recorder import Recorder

NOT_RECORDED = ("not verified: the filter settings and estimates (not recorded); truth and "
                "readings verified")


@pytest.fixture
def scenario_file(tmp_path):
    p = tmp_path / "rec_test.toml"
    p.write_text(SCENARIO)
    return p


def record_driver_run(scenario_file, out, seed=7, seconds=20.0):
    """Record the scenario's own driver, as ``run`` would drive it."""
    sc = load_scenario(scenario_file)
    with Recorder(out, sc, seed, ["ekf", "dead_reckoning"], {}) as rec:
        for k in range(1, round(seconds / sc.dt) + 1):
            rec.record_tick(k, None, [])
    return sc


def test_headless_replay_prints_the_same_metrics_as_run(scenario_file, tmp_path, capsys):
    out = tmp_path / "run.jsonl"
    sc = record_driver_run(scenario_file, out)
    assert main(["replay", str(out), "--headless", "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    ref = run_headless(sc, ["ekf", "dead_reckoning"], seed=7, duration=20.0).as_json()
    assert got["truth_checksum"] == ref["truth_checksum"]
    assert got["steps"] == ref["steps"] == 200
    assert got["measurements"] == ref["measurements"]
    for name in ("ekf", "dead_reckoning"):
        for key in ("pos_rmse_m", "heading_rmse_rad", "mse_x", "mse_y", "mse_theta", "anees"):
            assert got["filters"][name][key] == ref["filters"][name][key]
    # a bare Recorder (no runner attached) records no filter settings, and says so
    assert got["replay"]["checksum_status"] == NOT_RECORDED


def test_replay_text_output_says_the_checksum_was_verified(scenario_file, tmp_path, capsys):
    out = tmp_path / "run.jsonl"
    _, _, _, sim = live_run(scenario_file, out, ticks=50)
    assert main(["replay", str(out), "--headless", "--filter", "ukf"]) == 0
    text = capsys.readouterr().out
    assert f"truth checksum {sim.truth_checksum}: not verified: the estimates (other filters" in text
    assert "; truth and readings verified" in text
    assert "ukf" in text and "pos RMSE" in text


def test_replay_set_overrides_reach_the_filter(scenario_file, tmp_path, capsys):
    out = tmp_path / "run.jsonl"
    live_run(scenario_file, out, ticks=30)
    assert main(["replay", str(out), "--headless", "--json", "--filter", "ekf",
                 "--set", "ekf.no_such_param=1"]) == 2
    assert "no_such_param" in capsys.readouterr().err


def test_replay_bad_files_exit_2_with_one_line(tmp_path, capsys):
    assert main(["replay", str(tmp_path / "missing.jsonl"), "--headless"]) == 2
    err = capsys.readouterr().err.strip()
    assert "missing.jsonl" in err and "\n" not in err
    bad = tmp_path / "bad.jsonl"
    bad.write_text('{"type": "header", "format": "beacon-sim-recording", "version": 7}\n')
    assert main(["replay", str(bad), "--headless"]) == 2
    err = capsys.readouterr().err.strip()
    assert "version 7" in err and "bad.jsonl:1" in err and "\n" not in err


def test_replay_mismatch_exits_2_naming_the_tick(scenario_file, tmp_path, capsys):
    out = tmp_path / "run.jsonl"
    live_run(scenario_file, out, ticks=40)
    lines = out.read_text().splitlines()
    header = json.loads(lines[0])
    header["seed"] += 1  # another seed: the truth differs from tick 1 on
    out.write_text("\n".join([json.dumps(header), *lines[1:]]) + "\n")
    assert main(["replay", str(out), "--headless"]) == 2
    assert "at tick 1 " in capsys.readouterr().err


def test_without_headless_replays_in_the_window(scenario_file, tmp_path, capsys):
    """Without --headless the window replays (the dummy SDL driver here) and reports the
    checksum status when the recording ends."""
    out = tmp_path / "run.jsonl"
    live_run(scenario_file, out, ticks=20)
    assert main(["replay", str(out), "--frames", "200"]) == 0
    assert "truth checksum verified" in capsys.readouterr().err
