"""g2o files: planar pose graphs and landmark graphs, read into a
:class:`~beacon_sim.filters.graph.graph.FactorGraph`.

Lines read (whitespace-separated; g2o's own names)::

    VERTEX_SE2  id x y theta                     a pose [m, m, rad]
    VERTEX_XY   id x y                           a point landmark [m]
    EDGE_SE2    i j dx dy dtheta  I11 I12 I13 I22 I23 I33
                                                 pose j seen from pose i, the upper triangle
                                                 of its information matrix
    EDGE_SE2_XY i j dx dy  I11 I12 I22           landmark j in pose i's frame
    FIX id                                       a pose held fixed (the gauge)

Other line types are counted and named in the graph's ``notes`` (not silently dropped). The
vertices' own values are the initial guess. With no FIX line the first pose (lowest ID) is
held fixed. An EDGE_SE2 between consecutive pose IDs is labelled ``odometry``, any other
``loop closure``; EDGE_SE2_XY edges ``landmark``.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np

from beacon_sim.errors import BeaconSimError
from beacon_sim.filters.graph.graph import EdgeSet, FactorGraph


class G2oError(BeaconSimError):
    """A g2o file that cannot be read: the file, the line and what was expected."""


_FIELDS = {"VERTEX_SE2": 4, "VERTEX_XY": 3, "EDGE_SE2": 11, "EDGE_SE2_XY": 7, "FIX": 1}


def _upper(values: list[float], d: int) -> np.ndarray:
    """A symmetric (d, d) matrix from its upper triangle, row by row."""
    M = np.zeros((d, d))
    M[np.triu_indices(d)] = values
    return M + np.triu(M, 1).T


def read_g2o(path: str | Path) -> FactorGraph:
    """The graph in ``path`` (see the module)."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise G2oError(f"{path}: cannot read the g2o file ({exc.strerror or exc})") from None
    poses: dict[int, list[float]] = {}
    marks: dict[int, list[float]] = {}
    se2: list[tuple[int, int, list[float]]] = []
    xy: list[tuple[int, int, list[float]]] = []
    fixed: list[int] = []
    other: Counter[str] = Counter()
    for n, line in enumerate(text.splitlines(), 1):
        parts = line.split()
        if not parts or parts[0].startswith("#"):
            continue
        tag = parts[0]
        if tag not in _FIELDS:
            other[tag] += 1
            continue
        want = _FIELDS[tag]
        if len(parts) - 1 < want:
            raise G2oError(f"{path}, line {n}: {tag} needs {want} numbers, found {len(parts) - 1}")
        try:
            ids = [int(p) for p in parts[1:3 if tag.startswith("EDGE") else 2]]
            nums = [float(p) for p in parts[1 + len(ids):1 + want]]
        except ValueError:
            raise G2oError(f"{path}, line {n}: {tag}: expected integer IDs and numbers, got "
                           f"{' '.join(parts[1:1 + want])!r}") from None
        if not all(np.isfinite(nums)):
            raise G2oError(f"{path}, line {n}: {tag}: a value is not finite")
        if tag == "VERTEX_SE2":
            poses[ids[0]] = nums
        elif tag == "VERTEX_XY":
            marks[ids[0]] = nums
        elif tag == "EDGE_SE2":
            se2.append((ids[0], ids[1], nums))
        elif tag == "EDGE_SE2_XY":
            xy.append((ids[0], ids[1], nums))
        else:
            fixed.append(ids[0])
    if not poses:
        raise G2oError(f"{path}: no VERTEX_SE2 line: expected a planar pose graph")
    pose_ids = np.array(sorted(poses), dtype=np.int64)
    mark_ids = np.array(sorted(marks), dtype=np.int64)
    prow = {int(v): k for k, v in enumerate(pose_ids)}
    mrow = {int(v): k for k, v in enumerate(mark_ids)}

    def row(table: dict[int, int], vid: int, what: str, kind: str) -> int:
        if vid not in table:
            raise G2oError(f"{path}: {kind} names vertex {vid}, which is not a {what}")
        return table[vid]

    edges = []
    if se2:
        i = np.array([row(prow, a, "VERTEX_SE2", "EDGE_SE2") for a, _, _ in se2])
        j = np.array([row(prow, b, "VERTEX_SE2", "EDGE_SE2") for _, b, _ in se2])
        z = np.array([v[:3] for _, _, v in se2])
        info = np.array([_upper(v[3:9], 3) for _, _, v in se2])
        seq = np.array([b == a + 1 for a, b, _ in se2])
        for mask, label in ((seq, "odometry"), (~seq, "loop closure")):
            if mask.any():
                edges.append(EdgeSet("pose", label, i[mask], j[mask], z[mask], info[mask]))
    if xy:
        i = np.array([row(prow, a, "VERTEX_SE2", "EDGE_SE2_XY") for a, _, _ in xy])
        j = np.array([row(mrow, b, "VERTEX_XY", "EDGE_SE2_XY") for _, b, _ in xy])
        z = np.array([v[:2] for _, _, v in xy])
        info = np.array([_upper(v[2:5], 2) for _, _, v in xy])
        edges.append(EdgeSet("point", "landmark", i, j, z, info))
    fix = tuple(sorted({row(prow, f, "VERTEX_SE2", "FIX") for f in fixed})) or (0,)
    notes = [f"{count} {tag} line(s) not read" for tag, count in sorted(other.items())]
    return FactorGraph(np.array([poses[int(v)] for v in pose_ids]),
                       np.array([marks[int(v)] for v in mark_ids]).reshape(-1, 2), edges, fix,
                       pose_ids, mark_ids, str(path), notes)


__all__ = ["G2oError", "read_g2o"]
