"""Graph SLAM on a simulated drive beside EKF-SLAM: the figures ``beacon-sim graph SCENARIO``
prints and docs/smoothing.md's table.

One run: the scenario driven with ``ekf_slam`` (not given the map), its ticks turned into a
factor graph (``runs/graph_slam.py``) and solved by Gauss-Newton; the absolute trajectory
error (ATE, RMS position error) of the graph's poses, of EKF-SLAM's estimates and of dead
reckoning at the graph's pose ticks, and the map's GOSPA. Over seeds: pooled ATE with 95 %
bootstrap intervals over runs.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from beacon_sim.core.scenario import Scenario
from beacon_sim.evaluation import intervals
from beacon_sim.evaluation.slam_metrics import gospa
from beacon_sim.evaluation.slam_run import GOSPA_CUTOFF_M
from beacon_sim.filters.graph.solver import GraphSolver, StepReport
from beacon_sim.runs.graph_slam import DriveGraph, drive_graph
from beacon_sim.runs.headless import RunResult, run_headless

#: The filter graph SLAM is set beside.
PEER = "ekf_slam"


def drive(scenario: Scenario, seed: int, duration: float | None = None) -> tuple[RunResult, DriveGraph]:
    """A run of ``scenario`` with EKF-SLAM, and its factor graph."""
    res = run_headless(scenario, [PEER], seed=seed, duration=duration, step_limit_s=None)
    return res, drive_graph(scenario, res.steps)


def run_sums(scenario: Scenario, res: RunResult, dg: DriveGraph, solved: GraphSolver) -> dict[str, float]:
    """Squared position errors summed over the graph's pose ticks: graph, EKF-SLAM, dead
    reckoning; ``n`` the tick count; the map's GOSPA of graph and EKF-SLAM."""
    truth = np.vstack([scenario.initial_pose, res.truth])[dg.ticks]
    ticks, means, _ = res.filters.series(PEER)
    ekf = np.vstack([np.asarray(scenario.initial_pose, dtype=float)[None], means[:, 0]])
    full = np.full((len(res.steps) + 1, 3), np.nan)
    full[0] = ekf[0]
    full[ticks] = ekf[1:]
    out = {"n": float(len(dg.ticks))}
    for key, est in (("graph", solved.graph.poses), (PEER, full[dg.ticks]), ("odometry", dg.graph.poses)):
        e = est[:, :2] - truth[:, :2]
        out[key] = float(np.sum(e * e))
    beacons = np.asarray(scenario.world.beacon_xy, dtype=float)
    out["graph_gospa"] = gospa(solved.graph.landmarks, beacons, c=GOSPA_CUTOFF_M).value
    flt = res.runner.tracks[PEER].filter
    lm = flt.landmarks() if flt is not None else None  # type: ignore[attr-defined]
    out[f"{PEER}_gospa"] = (gospa(np.asarray(lm.means, dtype=float).reshape(-1, 2), beacons,
                                  c=GOSPA_CUTOFF_M).value if lm is not None else float("nan"))
    return out


def solve_drive(scenario: Scenario, seed: int, duration: float | None = None, method: str = "gn",
                max_steps: int = 30) -> tuple[RunResult, DriveGraph, GraphSolver, list[StepReport]]:
    """One run, its graph and the solver after it converged (and the steps it took)."""
    res, dg = drive(scenario, seed, duration)
    solver = GraphSolver(dg.graph, method)
    reports = solver.solve(max_steps)
    return res, dg, solver, reports


def ate_table(scenario: Scenario, seeds: Sequence[int], duration: float | None = None) -> dict[str, Any]:
    """Pooled ATE [m] of graph SLAM, EKF-SLAM and odometry over runs with ``seeds``, with 95 %
    bootstrap intervals over runs, and the mean map GOSPA [m]."""
    sums = []
    for seed in seeds:
        res, dg, solver, _ = solve_drive(scenario, seed, duration)
        sums.append(run_sums(scenario, res, dg, solver))
    n = np.array([s["n"] for s in sums])
    out: dict[str, Any] = {"runs": len(sums)}
    for key in ("graph", PEER, "odometry"):
        v = np.array([s[key] for s in sums])
        out[key] = {"ate_m": float(np.sqrt(v.sum() / n.sum())),
                    "ate_m_ci": intervals.ratio_of_sums(v, n, sqrt=True)}
    out["graph"]["map_gospa_m"] = float(np.mean([s["graph_gospa"] for s in sums]))
    out[PEER]["map_gospa_m"] = float(np.mean([s[f"{PEER}_gospa"] for s in sums]))
    return out


__all__ = ["PEER", "ate_table", "drive", "run_sums", "solve_drive"]
