"""A factor graph over planar poses and point landmarks, and its edge classes.

Nodes: poses ``[x, y, theta]`` [m, m, rad] (world frame) and landmarks ``[x, y]`` [m].
Edges, one :class:`EdgeSet` per class, each with a measurement z, an information matrix
Omega (the inverse of z's covariance) and an error e(nodes), wrapped where it is an angle:

==================  ================  =====================================================
kind                nodes             error e (what g2o / the simulation's sensor model say)
==================  ================  =====================================================
``pose``            pose i, pose j    ``t2v(Z^-1 (X_i^-1 X_j))``   (g2o's EDGE_SE2)
``point``           pose i, mark j    ``R_i^T (l_j - t_i) - z``    (g2o's EDGE_SE2_XY)
``range_bearing``   pose i, mark j    ``[|d| - z_r, wrap(atan2(d) - theta_i - z_b)]``, d = l_j - t_i
``bearing``         pose i, mark j    ``[wrap(atan2(d) - theta_i - z_b)]``
``range``           pose i, mark j    ``[|d| - z_r]``
==================  ================  =====================================================

Each class's ``label`` (odometry, loop closure, landmark) is what the chi2 per class is
reported under. chi2 = sum over edges of ``e^T Omega e``. The Jacobians are analytic
(tests/filters/test_graph_slam.py holds them to finite differences); a node's update is additive
(``x + dx``, headings wrapped), as g2o's VertexSE2 and VertexPointXY.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from beacon_sim.core.angles import wrap

#: The edge kinds and their measurement sizes.
EDGE_CLASSES = {"pose": 3, "point": 2, "range_bearing": 2, "bearing": 1, "range": 1}


@dataclass
class EdgeSet:
    """The edges of one class: ``i`` (E,) pose indices, ``j`` (E,) pose or landmark indices,
    ``z`` (E, d) measurements, ``info`` (E, d, d) information matrices."""

    kind: str
    label: str
    i: np.ndarray
    j: np.ndarray
    z: np.ndarray
    info: np.ndarray

    def __post_init__(self) -> None:
        if self.kind not in EDGE_CLASSES:
            raise ValueError(f"edge kind {self.kind!r}: expected one of {', '.join(EDGE_CLASSES)}")
        d = EDGE_CLASSES[self.kind]
        self.i = np.asarray(self.i, dtype=np.int64).reshape(-1)
        self.j = np.asarray(self.j, dtype=np.int64).reshape(-1)
        self.z = np.asarray(self.z, dtype=float).reshape(-1, d)
        self.info = np.asarray(self.info, dtype=float).reshape(-1, d, d)

    def __len__(self) -> int:
        return int(self.i.shape[0])

    @property
    def to_landmark(self) -> bool:
        return self.kind != "pose"

    # -- errors and Jacobians -----------------------------------------------------------
    def errors(self, poses: np.ndarray, landmarks: np.ndarray) -> np.ndarray:
        """e (E, d) at the nodes ``poses`` (n, 3), ``landmarks`` (m, 2)."""
        return self.linearise(poses, landmarks, jacobians=False)[0]

    def linearise(self, poses: np.ndarray, landmarks: np.ndarray, jacobians: bool = True
                  ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
        """``(e (E, d), A = de/dx_i (E, d, 3), B = de/dx_j (E, d, 3 or 2))``."""
        xi = poses[self.i]
        c, s = np.cos(xi[:, 2]), np.sin(xi[:, 2])
        E = len(self)
        if self.kind == "pose":
            xj = poses[self.j]
            dx, dy = xj[:, 0] - xi[:, 0], xj[:, 1] - xi[:, 1]
            # Delta = X_i^-1 X_j: R_i^T (t_j - t_i), theta_j - theta_i
            ux, uy = c * dx + s * dy, -s * dx + c * dy
            cz, sz = np.cos(self.z[:, 2]), np.sin(self.z[:, 2])
            ex, ey = ux - self.z[:, 0], uy - self.z[:, 1]
            e = np.empty((E, 3))
            e[:, 0] = cz * ex + sz * ey          # R_z^T (Delta_t - t_z)
            e[:, 1] = -sz * ex + cz * ey
            e[:, 2] = wrap(xj[:, 2] - xi[:, 2] - self.z[:, 2])
            if not jacobians:
                return e, None, None
            # R_z^T R_i^T = R(theta_i + theta_z)^T
            ca, sa = np.cos(xi[:, 2] + self.z[:, 2]), np.sin(xi[:, 2] + self.z[:, 2])
            B = np.zeros((E, 3, 3))
            B[:, 0, 0], B[:, 0, 1] = ca, sa
            B[:, 1, 0], B[:, 1, 1] = -sa, ca
            B[:, 2, 2] = 1.0
            A = -B
            # d/dtheta_i of R_z^T R_i^T (t_j - t_i) = R_z^T [uy, -ux]
            A[:, 0, 2] = cz * uy + sz * (-ux)
            A[:, 1, 2] = -sz * uy + cz * (-ux)
            A[:, 2, 2] = -1.0
            return e, A, B
        lj = landmarks[self.j]
        dx, dy = lj[:, 0] - xi[:, 0], lj[:, 1] - xi[:, 1]
        if self.kind == "point":
            e = np.empty((E, 2))
            ux, uy = c * dx + s * dy, -s * dx + c * dy   # R_i^T (l - t_i)
            e[:, 0], e[:, 1] = ux - self.z[:, 0], uy - self.z[:, 1]
            if not jacobians:
                return e, None, None
            B = np.zeros((E, 2, 2))
            B[:, 0, 0], B[:, 0, 1], B[:, 1, 0], B[:, 1, 1] = c, s, -s, c
            A = np.zeros((E, 2, 3))
            A[:, :, :2] = -B
            A[:, 0, 2], A[:, 1, 2] = uy, -ux
            return e, A, B
        q = np.maximum(dx * dx + dy * dy, 1e-300)
        if self.kind == "range":
            r = np.sqrt(q)
            e = (r - self.z[:, 0])[:, None]
            if not jacobians:
                return e, None, None
            A = np.stack([-dx / r, -dy / r, np.zeros(E)], -1)[:, None, :]
            return e, A, np.stack([dx / r, dy / r], -1)[:, None, :]
        bearing = wrap(np.arctan2(dy, dx) - xi[:, 2] - self.z[:, -1])
        Ab = np.stack([dy / q, -dx / q, -np.ones(E)], -1)       # d bearing / d pose
        Bb = np.stack([-dy / q, dx / q], -1)                     # d bearing / d landmark
        if self.kind == "bearing":
            e = bearing[:, None]
            return (e, Ab[:, None, :], Bb[:, None, :]) if jacobians else (e, None, None)
        r = np.sqrt(q)
        e = np.stack([r - self.z[:, 0], bearing], -1)
        if not jacobians:
            return e, None, None
        A = np.stack([np.stack([-dx / r, -dy / r, np.zeros(E)], -1), Ab], 1)
        B = np.stack([np.stack([dx / r, dy / r], -1), Bb], 1)
        return e, A, B

    def chi2(self, poses: np.ndarray, landmarks: np.ndarray) -> np.ndarray:
        """Each edge's ``e^T Omega e`` (E,)."""
        e = self.errors(poses, landmarks)
        return np.einsum("ei,eij,ej->e", e, self.info, e)


@dataclass
class FactorGraph:
    """Poses (n, 3), landmarks (m, 2), the edge classes, and the poses held fixed (the
    gauge: by default the first). ``pose_ids`` / ``landmark_ids``: the names a file or a
    run gave the nodes (g2o vertex IDs, beacon IDs)."""

    poses: np.ndarray
    landmarks: np.ndarray
    edges: list[EdgeSet]
    fixed: tuple[int, ...] = (0,)
    pose_ids: np.ndarray | None = None
    landmark_ids: np.ndarray | None = None
    source: str = ""
    notes: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.poses = np.asarray(self.poses, dtype=float).reshape(-1, 3)
        self.landmarks = np.asarray(self.landmarks, dtype=float).reshape(-1, 2)

    @property
    def n_poses(self) -> int:
        return int(self.poses.shape[0])

    @property
    def n_landmarks(self) -> int:
        return int(self.landmarks.shape[0])

    @property
    def n_edges(self) -> int:
        return sum(len(es) for es in self.edges)

    def copy(self) -> FactorGraph:
        return FactorGraph(self.poses.copy(), self.landmarks.copy(), self.edges, self.fixed,
                           self.pose_ids, self.landmark_ids, self.source, list(self.notes))

    def chi2_by_class(self) -> dict[str, float]:
        """chi2 summed per edge label (odometry, loop closure, landmark, ...)."""
        out: dict[str, float] = {}
        for es in self.edges:
            out[es.label] = out.get(es.label, 0.0) + float(np.sum(es.chi2(self.poses, self.landmarks)))
        return out

    def chi2(self) -> float:
        return float(sum(self.chi2_by_class().values()))

    def first_landmark_pose(self) -> int | None:
        """The lowest pose index with a landmark edge (None: no landmark edge). In a drive's
        graph (the start pose fixed, odometry edges chaining pose k-1 to pose k) nothing but
        the odometry touches the poses up to this one, so at the optimum they are dead
        reckoning exactly; and a rigid motion of every later pose with the whole map changes
        no edge but the odometry edge into this pose: the map's frame is this pose's,
        and only the odometry before the first reading fixes it (docs/slam.md)."""
        firsts = [int(es.i.min()) for es in self.edges if es.to_landmark and len(es)]
        return min(firsts) if firsts else None

    def worst_edges(self, k: int) -> list[tuple[float, str, int, int]]:
        """The ``k`` edges of largest chi2: (chi2, label, i, j)."""
        rows: list[tuple[float, str, int, int]] = []
        for es in self.edges:
            c = es.chi2(self.poses, self.landmarks)
            top = np.argsort(c)[::-1][:k]
            rows += [(float(c[t]), es.label, int(es.i[t]), int(es.j[t])) for t in top]
        return sorted(rows, reverse=True)[:k]


__all__ = ["EDGE_CLASSES", "EdgeSet", "FactorGraph"]
