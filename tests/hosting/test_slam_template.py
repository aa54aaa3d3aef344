"""``beacon-sim new-filter --slam``: the SLAM template is written, passes the conformance
check, runs on the SLAM scenario as it is (mapping each beacon once), and its TODO, done as
its docstring says, is the built-in EKF-SLAM step for step."""

from __future__ import annotations

import numpy as np
import pytest

from beacon_sim.cli.main import main
from beacon_sim.core.angles import wrap
from beacon_sim.core.scenario import load_scenario
from beacon_sim.hosting import conformance
from beacon_sim.hosting.loading import load_filter_class
from beacon_sim.runs.headless import run_headless
from beacon_sim.templates import render_slam_template


@pytest.fixture
def slam_file(tmp_path, capsys):
    path = tmp_path / "my_slam.py"
    assert main(["new-filter", str(path), "--slam"]) == 0
    out = capsys.readouterr().out
    assert "MySlam" in out and "play slam_loop" in out
    return path


def test_template_compiles_and_refuses_bad_names(slam_file, tmp_path, capsys):
    compile(slam_file.read_text(), str(slam_file), "exec")
    assert "TODO" in slam_file.read_text() and "def landmarks" in slam_file.read_text()
    with pytest.raises(ValueError):
        render_slam_template("not valid", "x.py")
    assert main(["new-filter", str(tmp_path / "both.py"), "--slam", "--team"]) == 2
    assert "cannot be combined" in capsys.readouterr().err


def test_template_passes_the_conformance_check(slam_file):
    results = conformance.run_checks(f"{slam_file}:MySlam", load_scenario("slam_loop"))
    failed = [f"{r.name}: {r.message}" for r in results if not r.passed]
    assert results and not failed


def test_template_runs_as_it_is_and_maps_each_beacon_once(slam_file):
    sc = load_scenario("slam_loop")
    res = run_headless(sc, [f"{slam_file}:MySlam", "dead_reckoning"], seed=3, duration=30.0)
    mine, dr = res.runner.tracks["MySlam"], res.runner.tracks["dead_reckoning"]
    assert mine.failed is None
    np.testing.assert_allclose(np.array(mine.means), np.array(dr.means), atol=1e-12)
    lm = mine.filter.landmarks()
    assert len(set(lm.ids.tolist())) == len(lm.ids) > 3


def test_doing_the_todo_as_written_gives_the_built_in_ekf_slam(slam_file):
    cls = load_filter_class(f"{slam_file}:MySlam")

    def _correct(self, y, H, R):
        P = self.P
        S = H @ P @ H.T + R
        K = np.linalg.solve(S, H @ P).T
        self.s = self.s + K @ y
        self.s[2] = wrap(self.s[2])
        P = P - K @ S @ K.T
        self.P = 0.5 * (P + P.T)

    module = __import__(cls.__module__)
    module.Done = type("Done", (cls,), {"_correct": _correct})
    sc = load_scenario("slam_loop")
    res = run_headless(sc, [f"{cls.__module__}:Done", "ekf_slam"], seed=3, duration=40.0)
    a, b = res.runner.tracks["Done"], res.runner.tracks["ekf_slam"]
    assert a.failed is None
    np.testing.assert_allclose(np.array(a.means), np.array(b.means), atol=1e-8)
    la, lb = a.filter.landmarks(), b.filter.landmarks()
    assert la.ids.tolist() == lb.ids.tolist()
    np.testing.assert_allclose(la.means, lb.means, atol=1e-8)
    np.testing.assert_allclose(la.covs, lb.covs, atol=1e-10)


def test_template_is_lint_clean(slam_file):
    import shutil
    import subprocess
    import sys
    from pathlib import Path

    ruff = shutil.which("ruff") or str(Path(sys.executable).parent / "ruff")
    if not Path(ruff).exists():
        pytest.skip("ruff not installed")
    out = subprocess.run([ruff, "check", "--no-cache", "--isolated", "--line-length", "110",
                          "--select", "E,F,W,I,B,UP,NPY,RUF", str(slam_file)],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stdout + out.stderr
