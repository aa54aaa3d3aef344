"""Graph SLAM against the maths: the edge Jacobians against finite differences, the g2o
reader's values and errors, Gauss-Newton on a graph whose optimum is known, sparse and dense
solves and marginals agreeing, the published optima of the Intel and DLR graphs, and a
simulated drive's graph beating EKF-SLAM."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from graph_data import graph_file, synthetic_graph

from beacon_sim.cli.main import main
from beacon_sim.core.motion import move
from beacon_sim.core.scenario import load_any_scenario
from beacon_sim.filters.graph import EdgeSet, FactorGraph, GraphSolver, marginals
from beacon_sim.filters.graph.se2 import between, compose
from beacon_sim.filters.graph.solver import Factor, Layout, normal_equations
from beacon_sim.io.g2o import G2oError, read_g2o

KINDS = {"pose": 3, "point": 2, "range_bearing": 2, "bearing": 1, "range": 1}


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_edge_jacobians_match_finite_differences(kind):
    rng = np.random.default_rng(11)
    poses = np.column_stack([rng.uniform(-3, 3, (4, 2)), rng.uniform(-3, 3, 4)])
    marks = rng.uniform(-5, 5, (3, 2))
    d = KINDS[kind]
    i, j = np.array([0, 1, 2]), np.array([1, 2, 3]) if kind == "pose" else np.array([0, 1, 2])
    es = EdgeSet(kind, "x", i, j, rng.normal(size=(3, d)) * 0.3, np.tile(np.eye(d), (3, 1, 1)))
    _, A, B = es.linearise(poses, marks)
    h = 1e-6
    for e_idx in range(3):
        for col in range(3):
            dp = np.zeros_like(poses)
            dp[i[e_idx], col] = h
            num = (es.errors(poses + dp, marks) - es.errors(poses - dp, marks))[e_idx] / (2 * h)
            np.testing.assert_allclose(A[e_idx, :, col], num, atol=1e-6)
        other = B.shape[2]
        for col in range(other):
            if kind == "pose":
                dp = np.zeros_like(poses)
                dp[j[e_idx], col] = h
                num = (es.errors(poses + dp, marks) - es.errors(poses - dp, marks))[e_idx] / (2 * h)
            else:
                dm = np.zeros_like(marks)
                dm[j[e_idx], col] = h
                num = (es.errors(poses, marks + dm) - es.errors(poses, marks - dm))[e_idx] / (2 * h)
            np.testing.assert_allclose(B[e_idx, :, col], num, atol=1e-6)


def test_between_undoes_compose():
    rng = np.random.default_rng(2)
    a = np.column_stack([rng.normal(size=(5, 2)), rng.uniform(-3, 3, 5)])
    b = np.column_stack([rng.normal(size=(5, 2)), rng.uniform(-3, 3, 5)])
    np.testing.assert_allclose(between(a, compose(a, b)), np.column_stack([b[:, :2], b[:, 2]]), atol=1e-12)


def test_gauss_newton_reaches_the_optimum_sparse_and_dense_alike():
    g, P, L = synthetic_graph()
    dense = GraphSolver(g, "gn", sparse=False)
    sparse = GraphSolver(g, "gn", sparse=True)
    dense.solve(20, rel_tol=1e-13)
    sparse.solve(20, rel_tol=1e-13)
    np.testing.assert_allclose(dense.graph.poses, sparse.graph.poses, atol=1e-9)
    # the optimum: one more step moves nothing, and chi2 is near its expectation (dof = rows - unknowns)
    assert dense.step().step_norm < 1e-8
    layout = Layout(dense.graph)
    rows = sum(len(es) * es.z.shape[1] for es in g.edges)
    dof = rows - layout.size
    assert 0.6 * dof < dense.graph.chi2() < 1.4 * dof
    assert np.abs(dense.graph.poses[:, :2] - P[:, :2]).max() < 0.1
    assert np.abs(dense.graph.landmarks - L).max() < 0.1
    # per-class chi2 adds up to the total
    assert sum(dense.graph.chi2_by_class().values()) == pytest.approx(dense.graph.chi2())


def test_levenberg_marquardt_never_raises_chi2_and_reaches_the_same_optimum():
    g, _, _ = synthetic_graph(seed=8)
    lm = GraphSolver(g, "lm", lam=10.0)
    reports = lm.solve(60, rel_tol=1e-10)
    totals = [reports[0].total_before] + [r.total_after for r in reports]
    assert all(b <= a for a, b in itertools.pairwise(totals))
    gn = GraphSolver(g, "gn")
    gn.solve(30)
    assert lm.graph.chi2() == pytest.approx(gn.graph.chi2(), rel=1e-6)


def _drive_read_from(k: int) -> FactorGraph:
    """The synthetic drive without its loop closure and with no reading before pose ``k``."""
    g, _, _ = synthetic_graph(seed=9)
    odo, rb = g.edges[0], g.edges[2]
    late = rb.i >= k
    rb = EdgeSet(rb.kind, rb.label, rb.i[late], rb.j[late], rb.z[late], rb.info[late])
    return FactorGraph(g.poses, g.landmarks, [odo, rb], g.fixed)


def test_the_poses_up_to_the_first_reading_are_dead_reckoning_at_the_optimum():
    k = 6
    g = _drive_read_from(k)
    assert g.first_landmark_pose() == k
    gn = GraphSolver(g, "gn")
    gn.solve(30, rel_tol=1e-13)
    odo = g.edges[0]
    dead = [g.poses[0]]
    for z in odo.z[:k]:
        dead.append(compose(dead[-1], z))
    np.testing.assert_allclose(gn.graph.poses[:k + 1], np.array(dead), atol=1e-8)
    # the later poses are not: the readings moved them off dead reckoning
    for z in odo.z[k:]:
        dead.append(compose(dead[-1], z))
    assert np.abs(gn.graph.poses[k + 1:, :2] - np.array(dead)[k + 1:, :2]).max() > 0.01


def test_a_rigid_motion_of_the_map_and_the_later_poses_costs_only_the_edge_into_the_first_reading():
    k = 6
    g = _drive_read_from(k)
    turn, shift = 0.3, np.array([0.7, -0.4])
    c, s = np.cos(turn), np.sin(turn)
    rot = np.array([[c, -s], [s, c]])
    poses, marks = g.poses.copy(), g.landmarks @ rot.T + shift
    poses[k:, :2] = poses[k:, :2] @ rot.T + shift
    poses[k:, 2] += turn
    odo, rb = g.edges
    np.testing.assert_allclose(rb.chi2(poses, marks), rb.chi2(g.poses, g.landmarks), rtol=1e-9)
    before, after = odo.chi2(g.poses, g.landmarks), odo.chi2(poses, marks)
    moved = np.flatnonzero(~np.isclose(before, after, rtol=1e-9, atol=1e-12))
    np.testing.assert_array_equal(moved, [k - 1])
    assert FactorGraph(g.poses, g.landmarks, [odo]).first_landmark_pose() is None


def test_marginals_are_blocks_of_the_inverse_information():
    g, _, _ = synthetic_graph(seed=3, n=12, m=3)
    s = GraphSolver(g)
    s.solve(20)
    layout = Layout(s.graph)
    r, c, v, _ = normal_equations(s.graph, layout)
    H = np.zeros((layout.size, layout.size))
    np.add.at(H, (r, c), v)
    inv = np.linalg.inv(H)
    for sparse in (False, True):
        P, L = marginals(s.graph, sparse=sparse)
        np.testing.assert_allclose(P[0], 0.0)  # the fixed pose
        k = 5
        a = layout.pose_col[k]
        np.testing.assert_allclose(P[k], inv[a:a + 3, a:a + 3], rtol=1e-8, atol=1e-14)
        a = layout.mark_col[2]
        np.testing.assert_allclose(L[2], inv[a:a + 2, a:a + 2], rtol=1e-8, atol=1e-14)
    # the factorisation solves H x = b either way
    x = Factor(r, c, v, layout.size, sparse=True).solve(np.ones(layout.size))
    np.testing.assert_allclose(H @ x, np.ones(layout.size), atol=1e-8)


G2O = """# a tiny landmark graph
VERTEX_SE2 0 0.0 0.0 0.0
VERTEX_SE2 1 1.0 0.1 0.05
VERTEX_SE2 2 2.1 0.0 0.0
VERTEX_XY 7 1.0 2.0
EDGE_SE2 0 1 1.0 0.0 0.0 100 0 0 100 0 400
EDGE_SE2 1 2 1.0 0.0 0.0 100 0 0 100 0 400
EDGE_SE2 0 2 2.0 0.0 0.0 50 1 0 50 0 200
EDGE_SE2_XY 0 7 1.0 2.0 25 0 25
EDGE_SE2_XY 2 7 -1.0 2.0 25 0 25
VERTEX_SE3:QUAT 9 0 0 0 0 0 0 1
"""


def test_g2o_reader_reads_vertices_edges_and_labels(tmp_path):
    path = tmp_path / "tiny.g2o"
    path.write_text(G2O)
    g = read_g2o(path)
    assert g.n_poses == 3 and g.n_landmarks == 1 and g.n_edges == 5
    assert [(es.label, len(es)) for es in g.edges] == [("odometry", 2), ("loop closure", 1), ("landmark", 2)]
    np.testing.assert_array_equal(g.edges[1].info[0], [[50, 1, 0], [1, 50, 0], [0, 0, 200]])
    assert g.landmark_ids.tolist() == [7] and g.fixed == (0,)
    assert g.notes == ["1 VERTEX_SE3:QUAT line(s) not read"]
    s = GraphSolver(g)
    s.solve(10)
    assert s.graph.chi2() < 1e-2 * g.chi2()


@pytest.mark.parametrize(("text", "message"), [
    ("VERTEX_SE2 0 0 0\n", "line 1: VERTEX_SE2 needs 4 numbers, found 3"),
    ("VERTEX_SE2 0 0 0 x\n", "line 1: VERTEX_SE2: expected integer IDs and numbers"),
    ("VERTEX_SE2 0 0 0 0\nEDGE_SE2 0 5 1 0 0 1 0 0 1 0 1\n",
     "EDGE_SE2 names vertex 5, which is not a VERTEX_SE2"),
    ("VERTEX_XY 0 0 0\n", "no VERTEX_SE2 line"),
])
def test_g2o_reader_errors_name_the_file_and_the_line(tmp_path, text, message):
    path = tmp_path / "bad.g2o"
    path.write_text(text)
    with pytest.raises(G2oError, match=message) as info:
        read_g2o(path)
    assert str(path) in str(info.value)


@pytest.mark.parametrize(("name", "published", "initial", "max_steps"), [
    ("intel.g2o", 359.97, 1_795_139.0, 6),
    ("input_INTEL.g2o", 215.84, 5_149_721.0, 8),
])
def test_pose_graphs_reach_the_published_chi2_from_their_own_initial_values(name, published, initial,
                                                                             max_steps):
    g = read_g2o(graph_file(name))
    assert g.chi2() == pytest.approx(initial, rel=1e-6)
    s = GraphSolver(g)
    reports = s.solve(max_steps)
    assert s.graph.chi2() == pytest.approx(published, rel=0.01)
    assert len(reports) <= max_steps


@pytest.mark.slow
def test_dlr_landmark_graph_reaches_the_course_figure():
    g = read_g2o(graph_file("dlr.g2o"))
    assert (g.n_poses, g.n_landmarks) == (3297, 576)
    s = GraphSolver(g)
    reports = s.solve(15)
    assert reports[1].total_after > reports[1].total_before  # plain GN rises at the second step
    assert s.graph.chi2() == pytest.approx(56_860.35, rel=0.01)


def test_the_drive_graph_odometry_is_the_velocity_model_and_beats_ekf_slam():
    sc = load_any_scenario("slam_loop").robots[0].scenario
    from beacon_sim.evaluation.graph_slam_run import drive, run_sums

    res, dg = drive(sc, 4)
    g = dg.graph
    # the initial poses are the commands dead-reckoned with the velocity model
    x = np.array(sc.initial_pose, dtype=float)
    dr = [x]
    for st in res.steps:
        x = move(x, st.control.v, st.control.omega, st.dt)
        dr.append(x)
    np.testing.assert_allclose(g.poses[:, :2], np.array(dr)[dg.ticks, :2], atol=1e-9)
    assert g.fixed == (0,) and dg.ticks[0] == 0 and dg.ticks[-1] == len(res.steps)
    assert np.diff(dg.ticks).max() <= 10
    s = GraphSolver(g)
    s.solve(20)
    sums = run_sums(sc, res, dg, s)
    assert sums["graph"] < sums["ekf_slam"] < sums["odometry"]


def test_graph_command_headless_prints_each_step(capsys, tmp_path):
    path = tmp_path / "tiny.g2o"
    path.write_text(G2O)
    assert main(["graph", str(path), "--headless", "--json"]) == 0
    out = capsys.readouterr().out
    assert "loop closure" in out and "chi2 total" in out
    import json

    d = json.loads(out.strip().splitlines()[-1])
    assert d["final_chi2"] < d["initial_chi2"] and d["iterations"]


def test_graph_window_steps_and_saves_a_screenshot(tmp_path):
    import os

    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    path = tmp_path / "tiny.g2o"
    path.write_text(G2O)
    png = tmp_path / "g.png"
    assert main(["graph", str(path), "--steps", "2", "--frames", "3", "--sparsity", "--ellipses",
                 "--screenshot", str(png)]) == 0
    assert png.stat().st_size > 1000


def test_a_step_the_solver_cannot_take_is_said_in_the_window_and_moves_nothing():
    import os

    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    from beacon_sim.app.graph_window import GraphWindow

    # a landmark seen once by bearing only: nothing fixes its range, H is singular
    g = FactorGraph(np.zeros((2, 3)), np.array([[1.0, 1.0]]),
                    [EdgeSet("pose", "odometry", [0], [1], [[1.0, 0.0, 0.0]], np.eye(3)[None]),
                     EdgeSet("bearing", "landmark", [1], [0], [[0.3]], np.eye(1)[None])])
    w = GraphWindow(g, size=(900, 600))
    w.step()
    assert w.message.startswith("no step:") and w.solver.iteration == 0
    np.testing.assert_array_equal(w.solver.graph.poses, g.poses)
    w.draw()
