import json

from beacon_sim.cli.main import main


def test_run_json_has_the_design_shape(capsys):
    assert main(["run", "krejsa_bearing_only", "--duration", "5", "--seed", "3",
                 "--filter", "dead_reckoning", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["scenario"] == "krejsa_bearing_only" and d["seed"] == 3 and d["steps"] == 50
    assert len(d["truth_checksum"]) == 16
    row = d["filters"]["dead_reckoning"]
    for key in ("pos_rmse_m", "heading_rmse_rad", "mse_x", "mse_y", "mse_theta", "anees",
                "us_per_step"):
        assert isinstance(row[key], float)
    assert d["measurements"]["beacons"] > 0


def test_run_checksum_does_not_depend_on_filters(capsys):
    main(["run", "default", "--duration", "3", "--filter", "dead_reckoning", "--json"])
    a = json.loads(capsys.readouterr().out)["truth_checksum"]
    main(["run", "default", "--duration", "3", "--filter", "dead_reckoning", "--filter",
          "dead_reckoning", "--json"])
    b = json.loads(capsys.readouterr().out)["truth_checksum"]
    assert a == b


def test_run_text_summary(capsys):
    assert main(["run", "krejsa_bearing_only", "--duration", "40", "--filter", "dead_reckoning"]) == 0
    out = capsys.readouterr().out
    assert "steps 400" in out and "kidnap at 30.00 s" in out and "truth checksum" in out


def test_list(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    assert "default" in out and "ulps_circle" in out and "dead_reckoning" in out


def test_bad_arguments_exit_2(capsys):
    assert main(["run", "default", "--duration", "-1"]) == 2
    assert main(["run", "default", "--filter", "nosuchfilter"]) == 2
    assert main(["run"]) == 2
    assert main(["run", "default", "--set", "novalue"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 4 and all(line.startswith("beacon-sim") for line in err)


def test_a_filter_that_crashes_when_built_is_marked_failed_and_the_others_run(tmp_path, capsys):
    bad = tmp_path / "bad_filter.py"
    bad.write_text("class Bad:\n    def __init__(self, ctx):\n        raise RuntimeError('boom')\n"
                   "    def predict(self, c, dt): pass\n    def update(self, m): pass\n")
    assert main(["run", "default", "--duration", "2", "--filter", f"{bad}:Bad",
                 "--filter", "dead_reckoning", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert "boom" in d["filters"]["Bad"]["failed"]
    assert "failed" not in d["filters"]["dead_reckoning"]
    assert d["filters"]["dead_reckoning"]["pos_rmse_m"] >= 0.0


def test_a_filter_that_can_use_no_sensor_of_the_scenario_gets_a_note(capsys):
    assert main(["run", "default", "--duration", "1", "--filter", "kf"]) == 0
    err = capsys.readouterr().err
    assert "kf uses pose / position readings" in err and "only predicts" in err
    assert main(["run", "assignment_kf", "--duration", "1", "--filter", "kf"]) == 0
    assert "only predicts" not in capsys.readouterr().err
