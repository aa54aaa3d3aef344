"""MyGaussNewton: my own Gauss-Newton step for graph SLAM (docs/smoothing.md).

It runs as it is: each step builds the normal equations H dx = -b of the whole graph, edge
by edge, and moves every node down the gradient (dx = -b / the largest entry of H's
diagonal: chi2 falls, but slowly). Fill in the TODO (solve H dx = -b) and it is
Gauss-Newton, step for step the built-in solver's.

Try it (from the folder this file is in):

    beacon-sim graph slam_loop --solver ./my_gauss_newton.py:MyGaussNewton --headless
    beacon-sim graph slam_loop --solver ./my_gauss_newton.py:MyGaussNewton     # N: one step

The graph (``self.graph``, a FactorGraph): ``poses`` (n, 3) [m, m, rad] and ``landmarks``
(m, 2) [m], world frame; ``edges``, one EdgeSet per class (odometry, landmark readings, loop
closures), each with the nodes it joins (``i``: a pose, ``j``: a pose or a landmark), and
``linearise(poses, landmarks)`` giving every edge's error e (E, d) and its Jacobians
A = de/dx_i (E, d, 3) and B = de/dx_j (E, d, 3 or 2); ``info`` (E, d, d) is each edge's
information matrix Omega. chi2 = sum over edges of e^T Omega e. Pose ``graph.fixed`` stays
where it is (the gauge): it has no unknowns.
"""

from __future__ import annotations

import numpy as np

from beacon_sim.api import FactorGraph, GraphSolver, StepReport, wrap


class MyGaussNewton(GraphSolver):
    """One Gauss-Newton step per call of :meth:`step` (the graph window's N key)."""

    def columns(self) -> tuple[np.ndarray, np.ndarray, int]:
        """Where each node's unknowns sit in dx: pose p at ``pose_col[p]`` (-1: fixed),
        landmark l at ``mark_col[l]``, and the number of unknowns."""
        g = self.graph
        pose_col = np.full(g.n_poses, -1)
        free = [p for p in range(g.n_poses) if p not in g.fixed]
        pose_col[free] = 3 * np.arange(len(free))
        mark_col = 3 * len(free) + 2 * np.arange(g.n_landmarks)
        return pose_col, mark_col, 3 * len(free) + 2 * g.n_landmarks

    def normal_equations(self) -> tuple[np.ndarray, np.ndarray]:
        """H = sum J^T Omega J and b = sum J^T Omega e over every edge, J = [A B] the edge's
        Jacobian in its two nodes (a fixed pose's columns left out)."""
        g = self.graph
        pose_col, mark_col, n = self.columns()
        H = np.zeros((n, n))
        b = np.zeros(n)
        for es in g.edges:
            e, A, B = es.linearise(g.poses, g.landmarks)
            assert A is not None and B is not None
            for k in range(len(es)):
                ci = pose_col[es.i[k]]
                cj = mark_col[es.j[k]] if es.to_landmark else pose_col[es.j[k]]
                blocks = [(ci, A[k]), (cj, B[k])]
                for ca, Ja in blocks:
                    if ca < 0:
                        continue
                    ra = slice(ca, ca + Ja.shape[1])
                    b[ra] += Ja.T @ es.info[k] @ e[k]
                    for cb, Jb in blocks:
                        if cb >= 0:
                            H[ra, cb:cb + Jb.shape[1]] += Ja.T @ es.info[k] @ Jb
        return H, b

    def solve_normal_equations(self, H: np.ndarray, b: np.ndarray) -> np.ndarray:
        """The step dx.

        TODO: it takes a small step down the gradient. Gauss-Newton solves H dx = -b:
            return -np.linalg.solve(H, b)
        """
        return -b / np.max(np.diag(H))

    def step(self) -> StepReport:
        """One step: the normal equations at the current nodes, dx, every node moved by its
        part of dx (headings wrapped)."""
        g = self.graph
        before = g.chi2_by_class()
        H, b = self.normal_equations()
        dx = self.solve_normal_equations(H, b)
        pose_col, mark_col, n = self.columns()
        poses, landmarks = g.poses.copy(), g.landmarks.copy()
        for p, c in enumerate(pose_col):
            if c >= 0:
                poses[p] += dx[c:c + 3]
        poses[:, 2] = wrap(poses[:, 2])
        for m, c in enumerate(mark_col):
            landmarks[m] += dx[c:c + 2]
        self.graph = FactorGraph(poses, landmarks, g.edges, g.fixed, g.pose_ids, g.landmark_ids,
                                 g.source, g.notes)
        self.iteration += 1
        report = StepReport(self.iteration, "gn", before, self.graph.chi2_by_class(),
                            float(np.linalg.norm(dx)), True, 0.0, n)
        self.history.append(report)
        return report
