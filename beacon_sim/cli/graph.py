"""``beacon-sim graph SOURCE [--method gn|lm] [--steps N] [--headless] [--json] [--seed N]
[--duration S] [--frames N] [--screenshot PNG] [--ellipses] [--sparsity] [--size WxH]
[--solver FILE.py:Class]``: graph SLAM on a g2o file or on a simulated drive, solved step by
step (by the built-in solver, or by a user's subclass of it: ``new-filter --gauss-newton``).

SOURCE is a ``.g2o`` file (its own initial values) or a scenario (a drive with EKF-SLAM
beside it, its commands and readings the graph). Headless: every step's chi2 per edge class
(and, for a drive, the ATE of graph SLAM, EKF-SLAM and odometry). On screen: one step per key
(N or Space), the worst edges highlighted (docs/smoothing.md).
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from beacon_sim.cli.common import check_duration, check_frames
from beacon_sim.cli.play import parse_size
from beacon_sim.core.scenario import load_any_scenario
from beacon_sim.errors import UsageError
from beacon_sim.evaluation.graph_slam_run import PEER, drive, run_sums
from beacon_sim.filters.graph.graph import FactorGraph
from beacon_sim.filters.graph.solver import GraphSolver
from beacon_sim.io.g2o import read_g2o


def _row(it: Any, chi: dict[str, float], labels: list[str], ms: str) -> str:
    return f"{it:>5}" + "".join(f"{chi.get(k, 0.0):>16,.2f}" for k in labels) + \
        f"{sum(chi.values()):>18,.2f}{ms:>9}"


def load_solver(spec: str) -> type[GraphSolver]:
    """``FILE.py:Class``: a subclass of :class:`GraphSolver` from a user's file; one-line
    :class:`UsageError` otherwise."""
    from beacon_sim.hosting.loading import FilterLoadError, import_file

    path, _, name = spec.rpartition(":")
    if not path or not name:
        raise UsageError(f"--solver {spec}: expected FILE.py:Class")
    try:
        module = import_file(Path(path))
    except FilterLoadError as exc:
        raise UsageError(f"--solver {spec}: {exc}") from None
    cls = getattr(module, name, None)
    if not (isinstance(cls, type) and issubclass(cls, GraphSolver)):
        raise UsageError(f"--solver {spec}: {path} has no class {name} built on beacon_sim.GraphSolver")
    return cls


def iterate(graph: FactorGraph, method: str, steps: int | None,
            solver_cls: type[GraphSolver] = GraphSolver) -> tuple[GraphSolver, list[dict[str, Any]]]:
    """The solver (``solver_cls``) stepped ``steps`` times (None: until chi2 stops falling, at
    most 50), each step's figures printed as it goes."""
    solver = solver_cls(graph, method)
    labels = list(graph.chi2_by_class())
    print(f"{'iter':>5}" + "".join(f"{k:>16}" for k in labels) + f"{'chi2 total':>18}{'CPU ms':>9}")
    print(_row(0, graph.chi2_by_class(), labels, ""))
    rows = []
    for _ in range(steps if steps is not None else 50):
        t0 = time.process_time()
        r = solver.step()
        ms = 1e3 * (time.process_time() - t0)
        print(_row(r.iteration, r.chi2_after, labels, f"{ms:.0f}") + ("" if r.accepted else "  refused"))
        rows.append({"iteration": r.iteration, "chi2": r.chi2_after, "chi2_total": r.total_after,
                     "accepted": r.accepted, "cpu_ms": ms})
        if steps is None and abs(r.total_before - r.total_after) <= 1e-6 * r.total_before:
            break
    return solver, rows


def graph_command(args: argparse.Namespace) -> int:
    method = args.method
    if args.steps is not None and args.steps < 0:
        raise UsageError(f"--steps {args.steps}: expected a number of solver steps >= 0")
    solver_cls = GraphSolver if args.solver is None else load_solver(args.solver)
    truth_poses = truth_marks = None
    res = dg = None
    if args.source.endswith(".g2o") or Path(args.source).suffix == ".g2o":
        graph = read_g2o(args.source)
        for note in graph.notes:
            print(f"note: {args.source}: {note}")
        title = Path(args.source).name
    else:
        team = load_any_scenario(args.source)
        if not team.solo:
            raise UsageError(f"graph {args.source}: a single robot's scenario or a .g2o file")
        sc = team.robots[0].scenario
        check_duration(args.duration, sc)
        seed = sc.seed if args.seed is None else args.seed
        res, dg = drive(sc, seed, args.duration)
        graph = dg.graph
        for note in graph.notes:
            print(f"note: {note}")
        truth_poses = np.vstack([sc.initial_pose, res.truth])[dg.ticks]
        truth_marks = np.asarray(sc.world.beacon_xy, dtype=float)
        title = f"{sc.name}, seed {seed}"
    if not args.headless:
        check_frames(args.frames)
        if args.frames is not None:
            os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
        from beacon_sim.app.graph_window import show_graph  # pygame only when a window opens

        return show_graph(graph, method, args.frames, args.screenshot, args.steps or 0,
                          parse_size(args.size), args.ellipses, args.sparsity, truth_poses, truth_marks,
                          title, solver_cls)
    print(f"{title}: {graph.n_poses} poses, {graph.n_landmarks} landmarks, {graph.n_edges} edges "
          f"({', '.join(f'{len(e)} {e.label} ({e.kind})' for e in graph.edges)}); "
          + (f"{solver_cls.__name__} of {args.solver}" if args.solver else
             'Gauss-Newton' if method == 'gn' else 'Levenberg-Marquardt') + f", pose {graph.fixed[0]} fixed")
    solver, rows = iterate(graph, method, args.steps, solver_cls)
    data: dict[str, Any] = {"source": args.source, "poses": graph.n_poses, "landmarks": graph.n_landmarks,
                            "edges": graph.n_edges, "method": method, "initial_chi2": graph.chi2(),
                            "final_chi2": solver.graph.chi2(), "iterations": rows}
    if res is not None and dg is not None:
        sc = res.scenario
        sums = run_sums(sc, res, dg, solver)
        n = sums["n"]
        data["ate_m"] = {k: (sums[k] / n) ** 0.5 for k in ("graph", PEER, "odometry")}
        data["map_gospa_m"] = {"graph": sums["graph_gospa"], PEER: sums[f"{PEER}_gospa"]}
        print(f"ATE at the {int(n)} pose nodes: graph SLAM {data['ate_m']['graph']:.3f} m, {PEER} "
              f"{data['ate_m'][PEER]:.3f} m, odometry {data['ate_m']['odometry']:.3f} m; map GOSPA graph "
              f"{sums['graph_gospa']:.3f} m, {PEER} {sums[f'{PEER}_gospa']:.3f} m")
    if args.json:
        print(json.dumps(data, default=float))
    return 0


def add_parser(sub: Any) -> None:
    p = sub.add_parser("graph", help="graph SLAM on a g2o file or a simulated drive, step by step")
    p.add_argument("source", metavar="SOURCE", help="a .g2o file, or a scenario (a drive with EKF-SLAM)")
    p.add_argument("--method", choices=("gn", "lm"), default="gn",
                   help="Gauss-Newton (default) or Levenberg-Marquardt")
    p.add_argument("--steps", type=int, metavar="N",
                   help="solver steps (headless default: until chi2 stops falling; window: taken first)")
    p.add_argument("--headless", action="store_true", help="no window: print each step's chi2")
    p.add_argument("--json", action="store_true", help="with --headless: also print one JSON object")
    p.add_argument("--seed", type=int, metavar="N", help="a scenario's drive: its seed")
    p.add_argument("--duration", type=float, metavar="S", help="a scenario's drive: seconds")
    p.add_argument("--frames", type=int, help="on screen: quit after N frames")
    p.add_argument("--screenshot", metavar="PNG", help="on screen: save the last frame")
    p.add_argument("--ellipses", action="store_true", help="on screen: start with the 95 %% ellipses (E)")
    p.add_argument("--sparsity", action="store_true", help="on screen: start with H's sparsity shown (S)")
    p.add_argument("--size", default="1280x800", help="on screen: window size WxH in pixels")
    p.add_argument("--solver", metavar="FILE.py:Class",
                   help="step with your own solver class (a GraphSolver subclass: new-filter --gauss-newton)")


__all__ = ["add_parser", "graph_command", "iterate", "load_solver"]
