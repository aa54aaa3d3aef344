"""Graph SLAM on MRCLAM data (``mrclam --slam --graph``) and the incremental solve it uses:
the incremental solve reaches the batch optimum where the batch can reach it, drops a
reading off by pi and nothing else, and on the synthetic MRCLAM folder the graph maps the
square and follows the path better than odometry."""

from __future__ import annotations

import math

import numpy as np
import pytest
from graph_data import synthetic_graph
from mrclam_helpers import make_folder, surveyed_landmarks

from beacon_sim.cli.main import main
from beacon_sim.evaluation.slam_metrics import gospa
from beacon_sim.evaluation.slam_run import GOSPA_CUTOFF_M, mrclam_slam_figures
from beacon_sim.filters.graph import EdgeSet, FactorGraph, GraphSolver
from beacon_sim.filters.graph.incremental import solve_incrementally
from beacon_sim.io.mrclam import MrclamError, load_mrclam
from beacon_sim.runs.mrclam import run_mrclam
from beacon_sim.runs.mrclam.graph_slam import GRAPH_NAME


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    f = tmp_path_factory.mktemp("mrclam_graph") / "SyntheticSet"
    make_folder(f, seconds=30.0, seed=5)
    return f


@pytest.mark.parametrize("chunk", [1, 4, 50])
def test_the_incremental_solve_reaches_the_batch_optimum(chunk):
    g, _, _ = synthetic_graph(seed=4)
    batch = GraphSolver(g, "gn")
    batch.solve(30, rel_tol=1e-12)
    out, rep = solve_incrementally(g, chunk, "lm", rel_tol=1e-12)
    assert rep.dropped == 0 and rep.solves == math.ceil((g.n_poses - 1) / chunk)
    assert out.chi2() == pytest.approx(batch.graph.chi2(), rel=1e-7)
    np.testing.assert_allclose(out.poses, batch.graph.poses, atol=1e-6)
    np.testing.assert_allclose(out.landmarks, batch.graph.landmarks, atol=1e-6)
    assert g.chi2() > 10 * out.chi2()  # the input graph was left as it was


def test_a_reading_off_by_pi_is_dropped_and_nothing_else():
    g, _, _ = synthetic_graph(seed=6)
    clean = GraphSolver(g, "gn")
    clean.solve(30, rel_tol=1e-12)
    rb = g.edges[-1]
    flipped = rb.z[:1] + np.array([0.0, math.pi])
    bad = EdgeSet("range_bearing", "landmark", rb.i[:1], rb.j[:1], flipped, rb.info[:1])
    spoilt = FactorGraph(g.poses, g.landmarks, [*g.edges, bad], g.fixed)
    kept_in, _ = solve_incrementally(spoilt, 5, "lm", rel_tol=1e-12)
    assert np.abs(kept_in.landmarks - clean.graph.landmarks).max() > 0.01  # it spoils the map
    out, rep = solve_incrementally(spoilt, 5, "lm", outlier_chi2=13.8, rel_tol=1e-12)
    assert rep.dropped == 1
    np.testing.assert_allclose(out.landmarks, clean.graph.landmarks, atol=1e-6)


def test_the_first_edges_must_chain_the_poses():
    g, _, _ = synthetic_graph()
    with pytest.raises(ValueError, match="chain"):
        solve_incrementally(FactorGraph(g.poses, g.landmarks, g.edges[1:], g.fixed))


def test_graph_slam_on_the_synthetic_folder_maps_the_square(synthetic):
    d = load_mrclam(synthetic, 1)
    run = run_mrclam(d, ["ekf_slam", "dead_reckoning"], calibration="self", slam=True, graph=True,
                     record_maps=True)
    assert list(run.tracks) == ["ekf_slam", "dead_reckoning", GRAPH_NAME]
    assert run.map_given[GRAPH_NAME] is False
    figs = mrclam_slam_figures(run)
    g = figs[GRAPH_NAME]
    assert (g["map_landmarks"], g["map_missed"], g["map_false"]) == (5, 0, 0), g
    lm = run.tracks[GRAPH_NAME].filter.landmarks()
    gg = gospa(lm.means, surveyed_landmarks(synthetic), c=GOSPA_CUTOFF_M)
    assert math.sqrt(gg.localisation / len(gg.pairs)) < 0.1
    assert g["ate_m"] < figs["dead_reckoning"]["ate_m"], figs
    # its marginals are covariances; the window gets its final map
    assert np.all(np.linalg.eigvalsh(lm.covs) > 0)
    # the map's frame: the first pose with a reading is where dead reckoning put it
    flt = run.tracks[GRAPH_NAME].filter
    k = flt.first_reading
    assert k is not None and k > 0
    assert run.tracks[GRAPH_NAME].times[k] >= d.measurements[0, 0] - 1e-9
    np.testing.assert_allclose(run.tracks[GRAPH_NAME].means[:k + 1], flt.dead_reckoned[:k + 1], atol=1e-6)
    assert np.all(np.linalg.eigvalsh(run.tracks[GRAPH_NAME].covs[1:]) > 0)
    assert run.map_history[GRAPH_NAME].at(run.t_end) is not None
    ev = run.evaluate()[GRAPH_NAME]
    assert ev["pos_rmse_m"] == pytest.approx(g["ate_m"])
    # the same run twice is the same graph
    again = run_mrclam(d, ["dead_reckoning"], calibration="self", slam=True, graph=True)
    np.testing.assert_array_equal(again.tracks[GRAPH_NAME].means, run.tracks[GRAPH_NAME].means)


@pytest.mark.parametrize("extra, says", [
    (["--graph"], "--graph is graph SLAM: give --slam"),
    (["--graph", "--slam", "--unknown-ids"], "--graph needs the readings' barcodes"),
])
def test_graph_without_slam_or_barcodes_is_a_one_line_error(synthetic, capsys, extra, says):
    assert main(["mrclam", str(synthetic), "--robot", "1", "--headless", *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert says in err and "\n" not in err and "Traceback" not in err


def test_run_refuses_graph_without_slam(synthetic):
    with pytest.raises(MrclamError, match="--graph"):
        run_mrclam(load_mrclam(synthetic, 1), ["ekf"], graph=True)


def test_delayed_commands_shift_the_odometry_and_hold_the_first_command(synthetic):
    from beacon_sim.runs.mrclam.graph_slam import delayed, recorded_steps
    from beacon_sim.runs.mrclam.runners import run_span

    d = load_mrclam(synthetic, 1)
    assert delayed(d, 0.0) is d
    late = delayed(d, 0.2)
    np.testing.assert_array_equal(late.odometry[1:, 0], d.odometry[:, 0] + 0.2)
    np.testing.assert_array_equal(late.odometry[0], d.odometry[0])
    t0, t1 = run_span([d], 10.0)
    cal = calibration_for_self(d)
    now, later = recorded_steps(d, cal, t0, t1), recorded_steps(d, cal, t0, t1, 0.2)
    # each command starts 0.2 s later: the turn commanded up to a time is the undelayed one 0.2 s earlier

    def turn(steps, t):
        return sum(s.control.omega * s.dt for s in steps if s.time <= t + 1e-9)

    grid = np.arange(1.0, 9.0, 0.25)  # turns from 1 s on (the first command is held 0.2 s longer)
    shifted = max(abs(turn(later, t) - turn(later, 1.0) - turn(now, t - 0.2) + turn(now, 0.8)) for t in grid)
    unshifted = max(abs(turn(later, t) - turn(later, 1.0) - turn(now, t) + turn(now, 1.0)) for t in grid)
    assert shifted < 0.01 < unshifted, (shifted, unshifted)


def calibration_for_self(d):
    from beacon_sim.runs.mrclam import calibration_for

    return calibration_for(d, "self")


def test_without_pose_covariances_the_landmarks_keep_theirs(synthetic):
    from beacon_sim.runs.mrclam import calibration_for
    from beacon_sim.runs.mrclam.graph_slam import graph_slam_track
    from beacon_sim.runs.mrclam.runners import run_span

    d = load_mrclam(synthetic, 1)
    t0, t1 = run_span([d], 10.0)
    cal = calibration_for(d, "self")
    full, _ = graph_slam_track(d, cal, t0, t1)
    lean, _ = graph_slam_track(d, cal, t0, t1, pose_covariances=False)
    np.testing.assert_array_equal(lean.means, full.means)
    assert np.isnan(lean.covs[1:]).all() and np.isfinite(full.covs).all()
    np.testing.assert_allclose(lean.filter.landmarks().covs, full.filter.landmarks().covs, rtol=1e-9)
