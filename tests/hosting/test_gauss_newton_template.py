"""``beacon-sim new-filter --gauss-newton``: the graph SLAM solver template is written, runs as
it is (a gradient step: chi2 falls every step), builds the built-in solver's normal
equations, and its TODO, done as its docstring says, is the built-in Gauss-Newton step for
step; ``beacon-sim graph --solver`` steps it, and refuses what is not a solver in one line."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from graph_data import synthetic_graph

from beacon_sim.cli.main import main
from beacon_sim.filters.graph.solver import GraphSolver, Layout, normal_equations
from beacon_sim.hosting.loading import import_file


@pytest.fixture
def gn_class(tmp_path, capsys):
    path = tmp_path / "my_gn.py"
    assert main(["new-filter", str(path), "--gauss-newton"]) == 0
    out = capsys.readouterr().out
    assert "MyGn" in out and f"graph slam_loop --solver {path}:MyGn" in out
    assert "TODO" in path.read_text()
    return import_file(path).MyGn


def test_as_it_is_each_step_lowers_chi2_but_does_not_reach_the_optimum(gn_class):
    g, _, _ = synthetic_graph(seed=2)
    mine = gn_class(g)
    totals = [g.chi2()] + [mine.step().total_after for _ in range(5)]
    assert all(b < a for a, b in itertools.pairwise(totals)), totals
    gn = GraphSolver(g, "gn")
    gn.solve(20)
    assert totals[-1] > 2 * gn.graph.chi2()


def test_its_normal_equations_are_the_built_in_solvers(gn_class):
    g, _, _ = synthetic_graph(seed=3, n=12, m=3)
    H, b = gn_class(g).normal_equations()
    layout = Layout(g)
    rows, cols, vals, b_ref = normal_equations(g, layout)
    H_ref = np.zeros((layout.size, layout.size))
    np.add.at(H_ref, (rows, cols), vals)
    np.testing.assert_allclose(H, H_ref, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(b, b_ref, rtol=1e-12, atol=1e-9)


def test_doing_the_todo_as_written_gives_the_built_in_gauss_newton(gn_class):
    done = type("Done", (gn_class,), {"solve_normal_equations": lambda self, H, b: -np.linalg.solve(H, b)})
    g, _, _ = synthetic_graph(seed=5)
    mine, ref = done(g), GraphSolver(g, "gn", sparse=False)
    for _ in range(4):
        a, r = mine.step(), ref.step()
        assert a.total_after == pytest.approx(r.total_after, rel=1e-9)
        np.testing.assert_allclose(mine.graph.poses, ref.graph.poses, atol=1e-8)
        np.testing.assert_allclose(mine.graph.landmarks, ref.graph.landmarks, atol=1e-8)
    assert mine.iteration == 4 and len(mine.history) == 4


@pytest.mark.parametrize("spec, says", [
    ("nofile.py:X", "no such filter file"),
    ("{tmp}/my_gn.py:Missing", "has no class Missing built on beacon_sim.GraphSolver"),
    ("justaname", "expected FILE.py:Class"),
])
def test_a_bad_solver_is_a_one_line_error(gn_class, tmp_path, capsys, spec, says):
    assert main(["graph", "slam_loop", "--headless", "--steps", "1", "--duration", "2",
                 "--solver", spec.format(tmp=tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert says in err and "\n" not in err and "Traceback" not in err


def test_the_graph_window_steps_a_users_solver(gn_class, tmp_path, monkeypatch):
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    shot = tmp_path / "shot.png"
    assert main(["graph", "slam_loop", "--duration", "5", "--solver", f"{tmp_path}/my_gn.py:MyGn",
                 "--steps", "2", "--frames", "4", "--screenshot", str(shot)]) == 0
    assert shot.stat().st_size > 1000


def test_template_is_lint_clean(tmp_path):
    import shutil
    import subprocess
    import sys
    from pathlib import Path

    path = tmp_path / "my_gn.py"
    assert main(["new-filter", str(path), "--gauss-newton"]) == 0
    ruff = shutil.which("ruff") or str(Path(sys.executable).parent / "ruff")
    if not Path(ruff).exists():
        pytest.skip("ruff not installed")
    out = subprocess.run([ruff, "check", "--no-cache", "--isolated", "--line-length", "110",
                          "--select", "E,F,W,I,B,UP,NPY,RUF", str(path)],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stdout + out.stderr
