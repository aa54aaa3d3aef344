"""``beacon-sim new-filter --scan``: the scan template is written, passes ``check`` on the
corridor through the CLI, refuses to be combined with another kind, and, as it is, tracks
the robot in the office far better than dead reckoning does."""

from __future__ import annotations

import numpy as np
import pytest

from beacon_sim.cli.main import main
from beacon_sim.cli.new_filter import TEMPLATES
from beacon_sim.core.scenario import load_scenario
from beacon_sim.runs.headless import run_headless
from beacon_sim.templates import render_scan_template


@pytest.fixture
def scan_file(tmp_path, capsys):
    path = tmp_path / "my_scan.py"
    assert main(["new-filter", str(path), "--scan"]) == 0
    out = capsys.readouterr().out
    assert "MyScan" in out and "--scenario corridor" in out and "play office" in out
    assert "--filter mcl" in out
    return path


def test_scan_is_a_row_of_the_templates_table():
    render, _, scenario, beside = TEMPLATES["scan"]
    assert render is render_scan_template and scenario.strip() == "office" and beside == "mcl"


def test_template_compiles_has_todos_and_refuses_bad_names(scan_file):
    text = scan_file.read_text()
    compile(text, str(scan_file), "exec")
    assert "class MyScan(FilterBase)" in text and "TODO 1" in text and "LikelihoodField" in text
    assert "__CLASS__" not in text and "__FILE__" not in text
    with pytest.raises(ValueError):
        render_scan_template("not valid", "x.py")


@pytest.mark.parametrize("other", ["--team", "--slam"])
def test_scan_with_another_kind_is_a_one_line_error(tmp_path, capsys, other):
    target = tmp_path / "both.py"
    assert main(["new-filter", str(target), "--scan", other]) == 2
    err = capsys.readouterr().err.strip()
    assert "cannot be combined" in err and "--scan" in err and "\n" not in err
    assert not target.exists()


def test_template_passes_check_on_the_corridor_through_the_cli(scan_file, capsys):
    code = main(["check", f"{scan_file}:MyScan", "--scenario", "corridor"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "FAIL" not in out and "checks passed" in out


def test_template_as_it_is_tracks_in_the_office(scan_file):
    sc = load_scenario("office")
    res = run_headless(sc, [f"{scan_file}:MyScan", "dead_reckoning"], seed=1, duration=30.0)
    truth = np.asarray(res.true_poses).reshape(-1, 3)
    rmse = {}
    for name, track in res.runner.tracks.items():
        assert track.failed is None
        m = np.asarray(track.means)
        err = np.hypot(*(m[:, :2] - truth[-len(m):, :2]).T)
        rmse[name] = float(np.sqrt(np.mean(err[len(err) // 2:] ** 2)))
    # The scan keeps the cloud on the true pose (~2 cm); dead reckoning drifts (~20 cm).
    assert rmse["MyScan"] < 0.1
    assert rmse["MyScan"] < 0.5 * rmse["dead_reckoning"]
