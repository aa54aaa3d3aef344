"""Gauss-Newton and Levenberg-Marquardt on a :class:`~beacon_sim.filters.graph.graph.FactorGraph`.

One step linearises every edge at the current nodes and solves the normal equations::

    H dx = -b,   H = sum J^T Omega J,   b = sum J^T Omega e       (J: the edge's [A B])

over every pose but the fixed ones (the gauge) and every landmark, then moves the nodes by
dx (headings wrapped). Levenberg-Marquardt solves ``(H + lambda diag(H)) dx = -b`` instead
and keeps a step only when chi2 falls (lambda / 3 after a kept step, x 4 after a refused one).

The factorisation: H is sparse (each edge fills four blocks). With scipy installed (the
``science`` extra) a graph of more than :data:`DENSE_MAX` unknowns is solved by scipy's
sparse LU (SuperLU in its symmetric mode, a minimum-degree order), about 15 ms for
the Intel graph's 5,181 unknowns; numpy has no sparse factorisation, so smaller graphs (and
any graph without scipy, up to :data:`DENSE_LIMIT`) take a dense Cholesky (``numpy.linalg``).
Marginal covariances (:func:`marginals`) are blocks of H^-1 at the optimum, found by solving
H X = E for the block's columns with the same factorisation.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.optional import install_hint
from beacon_sim.errors import BeaconSimError
from beacon_sim.filters.graph.graph import FactorGraph

#: At or below this many unknowns the normal equations are solved densely.
DENSE_MAX = 600
#: Without scipy, the largest graph solved densely (more: an error naming the extra).
DENSE_LIMIT = 4000


def _scipy() -> Any:
    try:
        import scipy.sparse as sp
        import scipy.sparse.linalg as spla
    except ImportError:
        return None
    return sp, spla


@dataclass(frozen=True)
class StepReport:
    """What one solver step did: chi2 per edge class before and after, the step's size,
    whether it was kept (LM), lambda (LM; 0 for Gauss-Newton), the unknowns' count."""

    iteration: int
    method: str
    chi2_before: dict[str, float]
    chi2_after: dict[str, float]
    step_norm: float
    accepted: bool
    lam: float
    unknowns: int

    @property
    def total_before(self) -> float:
        return float(sum(self.chi2_before.values()))

    @property
    def total_after(self) -> float:
        return float(sum(self.chi2_after.values()))


class Layout:
    """Where each node's unknowns sit in dx: pose p at ``pose_col[p]`` (-1: fixed),
    landmark l at ``mark_col[l]``."""

    def __init__(self, graph: FactorGraph):
        fixed = np.zeros(graph.n_poses, dtype=bool)
        fixed[list(graph.fixed)] = True
        free = np.flatnonzero(~fixed)
        self.pose_col = np.full(graph.n_poses, -1, dtype=np.int64)
        self.pose_col[free] = 3 * np.arange(free.size)
        self.mark_col = 3 * free.size + 2 * np.arange(graph.n_landmarks, dtype=np.int64)
        self.size = 3 * free.size + 2 * graph.n_landmarks


def normal_equations(graph: FactorGraph, layout: Layout) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                                    np.ndarray]:
    """The triplets (rows, cols, values) of H and the vector b at the graph's nodes.

    Per edge class at once: J = [A B] (E, d, k), the edge's block ``J^T Omega J`` (E, k, k)
    and ``J^T Omega e`` (E, k) at the unknowns' columns; a fixed pose's rows and columns are
    left out."""
    rows, cols, vals = [], [], []
    b = np.zeros(layout.size)
    for es in graph.edges:
        if not len(es):
            continue
        e, A, B = es.linearise(graph.poses, graph.landmarks)
        assert A is not None and B is not None
        J = np.concatenate([A, B], axis=2)                        # (E, d, k)
        ci = layout.pose_col[es.i]
        cj = layout.mark_col[es.j] if es.to_landmark else layout.pose_col[es.j]
        nb = B.shape[2]
        idx = np.concatenate([ci[:, None] + np.arange(3), cj[:, None] + np.arange(nb)], axis=1)
        idx[ci < 0, :3] = -1
        idx[cj < 0, 3:] = -1
        OmJ = np.einsum("eij,ejk->eik", es.info, J)               # Omega J
        Hb = np.einsum("eji,ejk->eik", J, OmJ)                    # J^T Omega J (E, k, k)
        g = np.einsum("eji,ej->ei", OmJ, e)                       # J^T Omega e (E, k)
        ok = idx >= 0
        b += np.bincount(idx[ok], weights=g[ok], minlength=layout.size)
        pair = ok[:, :, None] & ok[:, None, :]
        k = idx.shape[1]
        rows.append(np.broadcast_to(idx[:, :, None], (len(es), k, k))[pair])
        cols.append(np.broadcast_to(idx[:, None, :], (len(es), k, k))[pair])
        vals.append(Hb[pair])
    if not rows:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0), b
    return np.concatenate(rows), np.concatenate(cols), np.concatenate(vals), b


class Factor:
    """A factorisation of H (sparse LU or dense Cholesky / LU): ``solve(B)`` for B (N,) or (N, k)."""

    def __init__(self, rows: np.ndarray, cols: np.ndarray, vals: np.ndarray, n: int, damping: float = 0.0,
                 sparse: bool | None = None):
        sci = _scipy()
        if sparse is None:
            sparse = sci is not None and n > DENSE_MAX
        if not sparse and n > DENSE_LIMIT:
            raise BeaconSimError(install_hint("scipy", f"a graph of {n} unknowns (scipy's sparse solver)"))
        self.sparse = sparse
        if sparse:
            sp, spla = sci
            H = sp.csc_matrix((vals, (rows, cols)), shape=(n, n))
            if damping:
                H = H + sp.diags(damping * H.diagonal())
            self.diag = H.diagonal()
            # H is symmetric positive definite: SuperLU's symmetric mode (diagonal pivots, a
            # minimum-degree order of H's own pattern) halves the factorisation's time
            self._lu = spla.splu(H.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                                 options={"SymmetricMode": True})
        else:
            H = np.zeros((n, n))
            np.add.at(H, (rows, cols), vals)
            if damping:
                H[np.diag_indices(n)] *= 1.0 + damping
            self.diag = np.diag(H).copy()
            self._H = H
            try:
                self._L: np.ndarray | None = np.linalg.cholesky(H)
            except np.linalg.LinAlgError:
                self._L = None   # not positive definite to rounding: LU instead

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        if self.sparse:
            return self._lu.solve(rhs)
        if self._L is not None:
            y = np.linalg.solve(self._L, rhs)
            return np.linalg.solve(self._L.T, y)
        return np.linalg.solve(self._H, rhs)


def apply_step(graph: FactorGraph, layout: Layout, dx: np.ndarray) -> FactorGraph:
    """A copy of ``graph`` with its nodes moved by dx (additive, headings wrapped)."""
    out = graph.copy()
    free = layout.pose_col >= 0
    cols = layout.pose_col[free]
    out.poses[free] += np.stack([dx[cols], dx[cols + 1], dx[cols + 2]], -1)
    out.poses[:, 2] = wrap(out.poses[:, 2])
    if graph.n_landmarks:
        out.landmarks += np.stack([dx[layout.mark_col], dx[layout.mark_col + 1]], -1)
    return out


class GraphSolver:
    """Steps a graph towards its least-squares optimum, one call of :meth:`step` at a time
    (the window's key), or :meth:`solve` until chi2 stops falling.

    ``method``: ``"gn"`` (Gauss-Newton) or ``"lm"`` (Levenberg-Marquardt, ``lam`` its start).
    ``sparse``: None chooses (scipy for large graphs), True / False forces.
    """

    def __init__(self, graph: FactorGraph, method: str = "gn", lam: float = 1e-4,
                 sparse: bool | None = None):
        if method not in ("gn", "lm"):
            raise ValueError(f"method {method!r}: expected 'gn' or 'lm'")
        self.graph = graph
        self.method = method
        self.lam = lam if method == "lm" else 0.0
        self.sparse = sparse
        self.layout = Layout(graph)
        self.iteration = 0
        self.history: list[StepReport] = []

    def step(self) -> StepReport:
        """One Gauss-Newton (or LM) step; the graph's nodes move (LM: only when chi2 falls)."""
        before = self.graph.chi2_by_class()
        rows, cols, vals, b = normal_equations(self.graph, self.layout)
        n = self.layout.size
        it = self.iteration + 1  # counted once the step is solved
        if self.method == "gn":
            dx = -Factor(rows, cols, vals, n, 0.0, self.sparse).solve(b)
            new = apply_step(self.graph, self.layout, dx)
            self.graph = new
            report = StepReport(it, "gn", before, new.chi2_by_class(),
                                float(np.linalg.norm(dx)), True, 0.0, n)
        else:
            while True:
                dx = -Factor(rows, cols, vals, n, self.lam, self.sparse).solve(b)
                new = apply_step(self.graph, self.layout, dx)
                after = new.chi2_by_class()
                ok = sum(after.values()) < sum(before.values())
                if ok or self.lam > 1e12:
                    break
                self.lam *= 4.0
            lam = self.lam
            if ok:
                self.graph = new
                self.lam = max(self.lam / 3.0, 1e-12)
            report = StepReport(it, "lm", before, after if ok else before,
                                float(np.linalg.norm(dx)), ok, lam, n)
        self.iteration = it
        self.history.append(report)
        return report

    def solve(self, max_steps: int = 50, rel_tol: float = 1e-6) -> list[StepReport]:
        """Steps until chi2 changes by less than ``rel_tol`` of itself (or ``max_steps``)."""
        out = []
        for _ in range(max_steps):
            r = self.step()
            out.append(r)
            if abs(r.total_before - r.total_after) <= rel_tol * max(r.total_before, 1e-300):
                break
        return out


def marginals(graph: FactorGraph, poses: list[int] | np.ndarray | None = None,
              landmarks: list[int] | np.ndarray | None = None, sparse: bool | None = None,
              chunk: int = 600) -> tuple[np.ndarray, np.ndarray]:
    """Marginal covariances at the graph's nodes: poses (k, 3, 3) [m^2, m^2, rad^2] (a fixed
    pose's is zero) and landmarks (l, 2, 2) [m^2], blocks of H^-1. ``poses`` / ``landmarks``:
    which (default all)."""
    layout = Layout(graph)
    rows, cols, vals, _ = normal_equations(graph, layout)
    fac = Factor(rows, cols, vals, layout.size, 0.0, sparse)
    if not fac.sparse:
        chunk = 3 * layout.size  # every column at once
    p_idx = np.arange(graph.n_poses) if poses is None else np.asarray(poses, dtype=np.int64)
    l_idx = np.arange(graph.n_landmarks) if landmarks is None else np.asarray(landmarks, dtype=np.int64)
    want = [(0, k, layout.pose_col[p], 3) for k, p in enumerate(p_idx) if layout.pose_col[p] >= 0]
    want += [(1, k, layout.mark_col[m], 2) for k, m in enumerate(l_idx)]
    P = np.zeros((p_idx.size, 3, 3))
    L = np.zeros((l_idx.size, 2, 2))
    for a in range(0, len(want), max(chunk // 3, 1)):
        part = want[a:a + max(chunk // 3, 1)]
        cols_ = np.concatenate([c + np.arange(d) for _, _, c, d in part])
        E = np.zeros((layout.size, cols_.size))
        E[cols_, np.arange(cols_.size)] = 1.0
        X = fac.solve(E)
        at = 0
        for kind, k, c, d in part:
            block = X[c:c + d, at:at + d]
            block = 0.5 * (block + block.T)
            if kind == 0:
                P[k] = block
            else:
                L[k] = block
            at += d
    return P, L


__all__ = ["DENSE_LIMIT", "DENSE_MAX", "Factor", "GraphSolver", "Layout", "StepReport", "apply_step",
           "marginals", "normal_equations"]
