"""``beacon-sim eval``: same data for every filter, --jobs does not change the results,
the files it writes, and one-line errors."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from beacon_sim.cli.main import main
from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.evaluation.metrics import nis, nis_batch
from beacon_sim.evaluation.report import table_lines
from beacon_sim.hosting.loading import build_filter
from beacon_sim.runs.headless import run_headless

ARGS = ["eval", "default", "--filter", "ekf", "--filter", "dead_reckoning", "--runs", "3",
        "--duration", "8", "--seed", "5"]


def _eval_json(capsys, *extra):
    assert main([*ARGS, *extra, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def _without_timing(obj):
    if isinstance(obj, dict):
        return {k: _without_timing(v) for k, v in obj.items() if k != "us_per_step"}
    if isinstance(obj, list):
        return [_without_timing(v) for v in obj]
    return obj


def test_jobs_1_and_2_give_identical_tables(capsys):
    one = _eval_json(capsys, "--jobs", "1")
    two = _eval_json(capsys, "--jobs", "2")
    assert _without_timing(one) == _without_timing(two)
    assert table_lines(one, timing=False) == table_lines(two, timing=False)
    assert one["runs"] == 3 and one["steps"] == 160
    assert set(one["filters"]) == {"ekf", "dead_reckoning"}
    assert one["pcrb"]["pos_rmse_m"] > 0


def test_every_run_is_the_headless_run_of_its_seed(capsys):
    """All filters see the simulation of seed + i, exactly as ``beacon-sim run`` does."""
    out = _eval_json(capsys, "--jobs", "1")
    sc = load_scenario("default")
    for i, checksum in enumerate(out["run_checksums"]):
        res = run_headless(sc, ["ekf", "dead_reckoning"], seed=5 + i, duration=8.0)
        assert res.truth_checksum == checksum
        ref = res.filter_summary()
        for name in ("ekf", "dead_reckoning"):
            run = out["filters"][name]["per_run"][i]
            assert run["pos_rmse_m"] == pytest.approx(ref[name]["pos_rmse_m"], rel=1e-12)
            assert run["anees"] == pytest.approx(ref[name]["anees"], rel=1e-9)


def test_cli_writes_csv_json_and_png_that_open(tmp_path, capsys):
    out = tmp_path / "ev"
    assert main([*ARGS, "--jobs", "1", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "RMSE/PCRB" in printed and "ekf" in printed
    with open(out / "eval.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["filter"] for r in rows] == ["ekf", "dead_reckoning"]
    with open(out / "eval_runs.csv", newline="") as fh:
        assert len(list(csv.DictReader(fh))) == 6
    doc = json.loads((out / "eval.json").read_text())
    for row in rows:
        assert float(row["pos_rmse_m"]) == doc["filters"][row["filter"]]["pos_rmse_m"]
    for key in ("scenario", "seed", "steps", "truth_checksum", "filters", "pcrb"):
        assert key in doc
    for key in ("pos_rmse_m", "heading_rmse_rad", "mse_x", "mse_y", "mse_theta", "anees",
                "us_per_step", "spread", "rmse_over_pcrb"):
        assert key in doc["filters"]["ekf"]
    plt = pytest.importorskip("matplotlib.pyplot")
    pngs = sorted(out.glob("*.png"))
    assert len(pngs) == 4
    for p in pngs:
        img = plt.imread(p)
        assert img.ndim == 3 and img.shape[0] > 100 and img.shape[1] > 100


@pytest.mark.parametrize("extra, word", [
    (["--runs", "0"], "--runs"),
    (["--jobs", "0"], "--jobs"),
    (["--duration", "-1"], "--duration"),
    (["--seed", "-3"], "--seed"),
    (["--filter", "nosuchfilter"], "nosuchfilter"),
    (["--set", "ekf.no_such_key=1", "--filter", "ekf"], "no_such_key"),
    (["--runs", "many"], "--runs"),
])
def test_bad_arguments_are_one_line_and_exit_2(capsys, extra, word):
    assert main(["eval", "default", "--duration", "1", *extra]) == 2
    err = capsys.readouterr().err
    assert word in err
    assert err.count("\n") == 1 and "Traceback" not in err


def test_unknown_scenario_is_one_line_and_exit_2(capsys):
    assert main(["eval", "no_such_scenario", "--runs", "1"]) == 2
    err = capsys.readouterr().err
    assert "no_such_scenario" in err and err.count("\n") == 1


@pytest.mark.parametrize("name", ["default", "krejsa_bearing_only", "ulps_circle", "assignment_kf"])
def test_batched_nis_equals_the_sum_of_per_tick_nis(name):
    sc = load_scenario(name)
    sim = Simulation(sc, 2)
    f = build_filter("dead_reckoning", sc, 2)
    sensors = {s.name: s for s in sc.model_sensors}
    records, means, covs = [], [], []
    total, dof = 0.0, 0
    for _ in range(300):
        step = sim.step()
        f.predict(step.control, step.dt)
        if step.measurements:
            m, c = f.estimate()
            records.append(step.measurements)
            means.append(m)
            covs.append(c)
            v, d = nis(step.measurements, sensors, m, c, sc.world)
            total += v
            dof += d
    got = nis_batch(records, np.array(means), np.array(covs), sensors, sc.world)
    assert dof > 0 and got[1] == dof
    assert got[0] == pytest.approx(total, rel=1e-10)


def test_eval_outputs_name_files_not_their_folders(tmp_path, capsys):
    """A scenario file and a filter file given by path; the printed JSON and the CSV
    and JSON files of --out name them (the scenario's name, the filter's class), never the
    folder they are in, since they are shared."""
    where = tmp_path / "where" / "they" / "are"
    where.mkdir(parents=True)
    root = Path(__file__).resolve().parents[2]
    shutil.copy(root / "scenarios" / "default.toml", where / "mine.toml")
    shutil.copy(root / "examples" / "student_ekf.py", where / "student_ekf.py")
    out = tmp_path / "o"
    assert main(["eval", str(where / "mine.toml"), "--filter", "ekf", "--filter",
                 f"{where / 'student_ekf.py'}:StudentEKF", "--runs", "2", "--duration", "3",
                 "--jobs", "1", "--out", str(out), "--json"]) == 0
    printed = capsys.readouterr().out
    assert "StudentEKF" in printed and str(where) not in printed
    written = [f for f in out.iterdir() if f.suffix in (".csv", ".json")]
    assert len(written) >= 3
    for f in written:
        assert str(where) not in f.read_text(encoding="utf-8"), f.name
