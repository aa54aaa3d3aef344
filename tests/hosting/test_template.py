"""``beacon-sim new-filter``: the template is written, passes the conformance check, runs as
it is (dead reckoning), and its TODO, done as it says, gives the tutorial's EKF."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from beacon_sim.cli.main import main
from beacon_sim.core.angles import wrap
from beacon_sim.core.scenario import load_scenario
from beacon_sim.hosting import conformance
from beacon_sim.hosting.loading import load_filter_class
from beacon_sim.runs.headless import run_headless
from beacon_sim.templates import class_name_for, render_template

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


@pytest.fixture
def template_file(tmp_path, capsys):
    path = tmp_path / "my_filter.py"
    assert main(["new-filter", str(path)]) == 0
    out = capsys.readouterr().out
    assert "MyFilter" in out and "beacon-sim play --filter" in out
    return path


def test_class_names():
    assert class_name_for(Path("my_filter.py")) == "MyFilter"
    assert class_name_for(Path("ekf-v2.py")) == "EkfV2"
    assert class_name_for(Path("2nd.py")) == "MyFilter"
    assert class_name_for(Path("class.py")) == "Class"
    with pytest.raises(ValueError):
        render_template("not valid", "x.py")


def test_template_compiles_and_points_to_the_core(template_file):
    text = template_file.read_text()
    compile(text, str(template_file), "exec")
    for pointer in ("motion.jacobian_state", "mm.range_bearing_jacobian", "mm.bearing_jacobian",
                    "process_cov", "wrap(", "TODO 1", "TODO 2", "class MyFilter(FilterBase)"):
        assert pointer in text


def test_refuses_to_overwrite_or_bad_names(template_file, tmp_path, capsys):
    before = template_file.read_text()
    assert main(["new-filter", str(template_file)]) == 2
    assert "exists" in capsys.readouterr().err
    assert template_file.read_text() == before
    assert main(["new-filter", str(tmp_path / "notpython.txt")]) == 2
    assert main(["new-filter", str(tmp_path / "no_dir" / "f.py")]) == 2
    err = capsys.readouterr().err
    assert ".py" in err and "no folder" in err


def test_template_passes_the_conformance_check(template_file):
    results = conformance.run_checks(f"{template_file}:MyFilter", load_scenario("default"))
    failed = [f"{r.name}: {r.message}" for r in results if not r.passed]
    assert results and not failed


def test_check_command_on_the_template(template_file, capsys):
    assert main(["check", f"{template_file}:MyFilter"]) == 0
    assert "FAIL" not in capsys.readouterr().out


def test_template_runs_as_it_is_and_is_dead_reckoning(template_file):
    res = run_headless(load_scenario("default"), [f"{template_file}:MyFilter", "dead_reckoning"],
                       seed=3, duration=10.0)
    mine, dr = res.runner.tracks["MyFilter"], res.runner.tracks["dead_reckoning"]
    assert mine.failed is None and len(mine.means) == len(res.steps)
    np.testing.assert_array_equal(np.array(mine.means), np.array(dr.means))
    np.testing.assert_array_equal(np.array(mine.covs), np.array(dr.covs))


def test_template_runs_from_the_command_line(template_file, capsys):
    assert main(["run", "default", "--filter", f"{template_file}:MyFilter", "--duration", "2"]) == 0
    out = capsys.readouterr().out
    assert "MyFilter" in out and "FAILED" not in out


def test_doing_todo_1_as_written_gives_the_tutorial_ekf(template_file):
    """Fill in ``_correct`` with the equations its docstring gives: on a range-bearing
    scenario the template then matches examples/student_ekf.py step for step."""
    cls = load_filter_class(f"{template_file}:MyFilter")

    def _correct(self, y, H, R):
        P = self.cov
        S = H @ P @ H.T + R
        K = np.linalg.solve(S, H @ P).T
        self.mean = self.mean + K @ y
        self.mean[2] = wrap(self.mean[2])
        I_KH = np.eye(3) - K @ H
        self.cov = I_KH @ P @ I_KH.T + K @ R @ K.T

    module = __import__(cls.__module__)
    done = type("Done", (cls,), {"_correct": _correct})
    module.Done = done
    spec_done = f"{cls.__module__}:Done"
    res = run_headless(load_scenario("default"), [spec_done, f"{EXAMPLES / 'student_ekf.py'}:StudentEKF"],
                       seed=3, duration=20.0)
    a, b = res.runner.tracks["Done"], res.runner.tracks["StudentEKF"]
    assert a.failed is None
    np.testing.assert_allclose(np.array(a.means), np.array(b.means), atol=1e-9)
    assert res.filter_summary()["Done"]["pos_rmse_m"] < 0.1


def test_template_is_lint_clean(template_file):
    ruff = shutil.which("ruff") or str(Path(__import__("sys").executable).parent / "ruff")
    if not Path(ruff).exists():
        pytest.skip("ruff not installed")
    out = subprocess.run([ruff, "check", "--no-cache", "--isolated", "--line-length", "110",
                          "--select", "E,F,W,I,B,UP,NPY,RUF", str(template_file)],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stdout + out.stderr
