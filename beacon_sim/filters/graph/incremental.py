"""A long drive's graph solved as it grows: the initial values a batch solver needs.

Gauss-Newton (or Levenberg-Marquardt) from dead-reckoned initial values falls into a wrong
minimum when the odometry has lost tens of degrees of heading (a real robot's whole run:
on MRCLAM the map came out turned by 98 degrees). :func:`solve_incrementally` solves the
graph over its first ``chunk`` poses, then adds the next poses (placed by composing each new
odometry edge onto the solved pose before it) and the landmarks first read from them (placed
from that reading at the solved pose), solves again from there, and so on to the last pose:
each solve starts near its optimum, as an online smoother (iSAM) keeps it.

Optionally, at the end, the worst landmark edges are dropped while any edge's chi2 at the
optimum exceeds ``outlier_chi2``: each round drops those above a quarter of the worst (and
above ``outlier_chi2``) and solves again, at most :data:`OUTLIER_ROUNDS` rounds (a reading
off by pi is one wrong edge a least-squares solver cannot outvote; it also pulls its
neighbours' edges past the threshold, which is why the worst go first).

Needs a graph whose poses are in time order, pose ``k`` joined to ``k - 1`` by an odometry
edge (``pose`` kind, first edge set), as ``runs/graph_slam.py`` builds it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from beacon_sim.filters.graph.graph import EdgeSet, FactorGraph
from beacon_sim.filters.graph.se2 import compose
from beacon_sim.filters.graph.solver import GraphSolver

#: The most rounds of outlier removal after the solve.
OUTLIER_ROUNDS = 10


@dataclass(frozen=True)
class IncrementalReport:
    """What :func:`solve_incrementally` did: the solves (one per chunk and the last), the
    solver steps in all, the final chi2 and the landmark edges dropped as outliers."""

    solves: int
    steps: int
    chi2: float
    dropped: int


def _place_landmark(pose: np.ndarray, es: EdgeSet, k: int) -> np.ndarray | None:
    """Landmark position from edge ``k`` of ``es`` at ``pose``, for kinds that fix it."""
    x, y, th = pose
    if es.kind == "range_bearing":
        r, b = es.z[k]
        return np.array([x + r * np.cos(th + b), y + r * np.sin(th + b)])
    if es.kind == "point":
        c, s = np.cos(th), np.sin(th)
        return np.array([x + c * es.z[k, 0] - s * es.z[k, 1], y + s * es.z[k, 0] + c * es.z[k, 1]])
    return None


def _subgraph(graph: FactorGraph, poses: np.ndarray, marks: np.ndarray, n: int,
              known: np.ndarray) -> FactorGraph:
    """The graph over poses ``0..n-1`` and the landmarks ``known`` (bool (m,)), with their
    current values (landmarks renumbered in order)."""
    remap = np.full(graph.n_landmarks, -1, dtype=np.int64)
    remap[known] = np.arange(int(known.sum()))
    edges = []
    for es in graph.edges:
        if es.to_landmark:
            keep = (es.i < n) & known[es.j]
            j = remap[es.j[keep]]
        else:
            keep = (es.i < n) & (es.j < n)
            j = es.j[keep]
        if keep.any():
            edges.append(EdgeSet(es.kind, es.label, es.i[keep], j, es.z[keep], es.info[keep]))
    return FactorGraph(poses[:n], marks[known], edges, graph.fixed)


def solve_incrementally(graph: FactorGraph, chunk: int = 200, method: str = "lm",
                        max_steps: int = 30, outlier_chi2: float | None = None,
                        rel_tol: float = 1e-6) -> tuple[FactorGraph, IncrementalReport]:
    """The graph's optimum, reached by solving it as it grows ``chunk`` poses at a time (see
    the module); returns the solved graph (a copy: the nodes moved, ``graph`` untouched; with
    ``outlier_chi2``, without the dropped edges) and a report."""
    odo = graph.edges[0]
    if odo.kind != "pose" or not np.array_equal(odo.j, odo.i + 1):
        raise ValueError("solve_incrementally: the first edge set must chain pose k-1 to pose k")
    step_of = np.full(graph.n_poses, -1, dtype=np.int64)
    step_of[odo.j] = np.arange(len(odo))
    poses = graph.poses.copy()
    marks = graph.landmarks.copy()
    known = np.zeros(graph.n_landmarks, dtype=bool)
    first = [(es, np.argsort(es.i, kind="stable")) for es in graph.edges if es.to_landmark]
    solves = steps = 0
    n_done = 1
    while n_done < graph.n_poses:
        n = min(graph.n_poses, n_done + chunk)
        for k in range(n_done, n):
            poses[k] = compose(poses[k - 1], odo.z[step_of[k]])
        for es, order in first:
            for e in order[(es.i[order] >= n_done) & (es.i[order] < n)]:
                if not known[es.j[e]]:
                    xy = _place_landmark(poses[es.i[e]], es, int(e))
                    if xy is not None:
                        marks[es.j[e]] = xy
                        known[es.j[e]] = True
        sub = _subgraph(graph, poses, marks, n, known)
        solver = GraphSolver(sub, method)
        steps += len(solver.solve(max_steps, rel_tol))
        solves += 1
        poses[:n] = solver.graph.poses
        marks[known] = solver.graph.landmarks
        n_done = n
    out = graph.copy()
    out.poses, out.landmarks = poses, marks
    dropped = 0
    limit = float("inf") if outlier_chi2 is None else float(outlier_chi2)
    for _ in range(OUTLIER_ROUNDS if outlier_chi2 is not None else 0):
        worst = max((float(es.chi2(out.poses, out.landmarks).max()) for es in out.edges
                     if es.to_landmark and len(es)), default=0.0)
        if worst <= limit:
            break
        cut = max(limit, worst / 4.0)
        edges = []
        for es in out.edges:
            if es.to_landmark:
                keep = es.chi2(out.poses, out.landmarks) <= cut
                dropped += int((~keep).sum())
                es = EdgeSet(es.kind, es.label, es.i[keep], es.j[keep], es.z[keep], es.info[keep])
            edges.append(es)
        out = FactorGraph(out.poses, out.landmarks, edges, graph.fixed, graph.pose_ids,
                          graph.landmark_ids, graph.source, list(graph.notes))
        solver = GraphSolver(out, method)
        steps += len(solver.solve(max_steps, rel_tol))
        solves += 1
        out = solver.graph
    return out, IncrementalReport(solves, steps, out.chi2(), dropped)


__all__ = ["OUTLIER_ROUNDS", "IncrementalReport", "solve_incrementally"]
