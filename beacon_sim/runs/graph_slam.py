"""Graph SLAM from a drive: a run's commands and beacon readings as a factor graph.

Nodes: the robot's pose at tick 0 (held fixed: the known start, the gauge), at every tick
with a beacon reading, at least every :data:`MAX_GAP` ticks and at the last tick; one
landmark per beacon ID seen (the map is not given). Edges:

- **odometry** between consecutive pose nodes: the commands of the ticks between them
  composed with the velocity model (``x += v dt cos th`` ...), its covariance propagated
  from the filters' motion noise model (``MotionNoise.control_std``, ``pose_std_at``)
  through the same steps, plus a floor of :data:`ODOMETRY_FLOOR` (a robot at a standstill
  has no noise at all under the scaled slip model, and an information matrix must exist);
- **landmark** edges, one per reading: ``range_bearing``, ``bearing`` or ``range`` (the
  sensor model's own noise from the scenario's model sensors), to the beacon's landmark.

Initial values: the poses dead-reckoned from the commands, each landmark placed from the
first range-bearing reading of it (a landmark never read with range and bearing is left
out, its edges too, with a note). Known correspondence (beacon IDs); readings without an ID
are left out with a note.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.scenario import Scenario
from beacon_sim.core.types import Step
from beacon_sim.filters.graph.graph import EdgeSet, FactorGraph
from beacon_sim.filters.graph.se2 import compose

#: The longest stretch [ticks] between two pose nodes without a reading.
MAX_GAP = 10
#: Standard deviations [m, m, rad] added to every odometry edge's covariance.
ODOMETRY_FLOOR = (1e-4, 1e-4, 1e-4)
#: The reading kinds that become landmark edges.
LANDMARK_KINDS = ("range_bearing", "bearing", "range")


@dataclass(frozen=True)
class DriveGraph:
    """The graph of a run and which tick each pose node is (``ticks`` (n,))."""

    graph: FactorGraph
    ticks: np.ndarray


def odometry(scenario: Scenario, steps: Sequence[Step]) -> tuple[np.ndarray, np.ndarray]:
    """The relative motion ``[dx, dy, dtheta]`` in the first pose's frame of the ``steps``'
    commands composed, and its covariance (3, 3) (see the module)."""
    noise = scenario.model_motion_noise
    delta = np.zeros(3)
    S = np.zeros((3, 3))
    for st in steps:
        v, w, dt = float(st.control.v), float(st.control.omega), st.dt
        sv, sw = noise.control_std(v, w)
        ps = np.broadcast_to(np.asarray(noise.pose_std_at(v, w), dtype=float), (3,))
        c, s = np.cos(delta[2]), np.sin(delta[2])
        J1 = np.array([[1.0, 0.0, -s * v * dt], [0.0, 1.0, c * v * dt], [0.0, 0.0, 1.0]])
        B = np.array([[c * dt, 0.0], [s * dt, 0.0], [0.0, dt]])      # d step / d (v, w)
        S = J1 @ S @ J1.T + B @ np.diag([float(sv) ** 2, float(sw) ** 2]) @ B.T + np.diag(ps**2)
        delta = compose(delta, np.array([v * dt, 0.0, w * dt]))
    return delta, S + np.diag(np.square(ODOMETRY_FLOOR))


def drive_graph(scenario: Scenario, steps: Sequence[Step], max_gap: int = MAX_GAP) -> DriveGraph:
    """The factor graph of a single robot's run (see the module)."""
    T = len(steps)
    read = [k + 1 for k, st in enumerate(steps)
            if any(m.kind in LANDMARK_KINDS and m.z.shape[0] for m in st.measurements)]
    node_ticks = sorted({0, T, *read})
    filled = [0]
    for t in node_ticks[1:]:
        while t - filled[-1] > max_gap:
            filled.append(filled[-1] + max_gap)
        filled.append(t)
    ticks = np.array(filled, dtype=np.int64)
    row = {int(t): k for k, t in enumerate(ticks)}
    poses = np.zeros((len(ticks), 3))
    poses[0] = scenario.initial_pose
    oi, oj, oz, oinfo = [], [], [], []
    for k in range(1, len(ticks)):
        d, S = odometry(scenario, steps[ticks[k - 1]:ticks[k]])
        poses[k] = compose(poses[k - 1], d)
        oi.append(k - 1)
        oj.append(k)
        oz.append(d)
        oinfo.append(np.linalg.inv(S))
    specs = {s.name: s for s in scenario.model_sensors}
    marks: dict[int, np.ndarray] = {}
    readings: dict[str, list[tuple[int, int, list[float], np.ndarray]]] = {k: [] for k in LANDMARK_KINDS}
    notes: list[str] = []
    unknown = 0
    for t, st in enumerate(steps, 1):
        for m in st.measurements:
            if m.kind not in LANDMARK_KINDS:
                continue
            spec = specs[m.sensor]
            p = row[t]
            for zrow, bid in zip(m.z.tolist(), m.beacon_ids.tolist(), strict=True):
                if bid < 0:
                    unknown += 1
                    continue
                if m.kind == "range_bearing":
                    info = np.diag([1.0 / spec.noise.range_std**2, 1.0 / spec.noise.bearing_std**2])
                    if bid not in marks:
                        x, y, th = poses[p]
                        a = th + zrow[1]
                        marks[bid] = np.array([x + zrow[0] * np.cos(a), y + zrow[0] * np.sin(a)])
                elif m.kind == "bearing":
                    info = np.array([[1.0 / spec.noise.bearing_std**2]])
                else:
                    info = np.array([[1.0 / spec.noise.range_std**2]])
                readings[m.kind].append((p, bid, zrow, info))
    if unknown:
        notes.append(f"{unknown} reading(s) without a beacon ID left out (graph SLAM here needs IDs)")
    ids = np.array(sorted(marks), dtype=np.int64)
    mrow = {int(b): k for k, b in enumerate(ids)}
    edges = [EdgeSet("pose", "odometry", np.array(oi, dtype=np.int64), np.array(oj, dtype=np.int64),
                     np.array(oz).reshape(-1, 3), np.array(oinfo).reshape(-1, 3, 3))]
    dropped = 0
    for kind, rows in readings.items():
        kept = [r for r in rows if r[1] in mrow]
        dropped += len(rows) - len(kept)
        if kept:
            edges.append(EdgeSet(kind, "landmark", np.array([r[0] for r in kept]),
                                 np.array([mrow[r[1]] for r in kept]),
                                 np.array([r[2] for r in kept]), np.array([r[3] for r in kept])))
    if dropped:
        notes.append(f"{dropped} reading(s) of beacons never read with range and bearing left out "
                     "(no initial value)")
    lm = np.array([marks[int(b)] for b in ids]).reshape(-1, 2)
    graph = FactorGraph(poses, lm, edges, (0,), ticks, ids, f"{scenario.name} run", notes)
    return DriveGraph(graph, ticks)


def wrap_heading(poses: np.ndarray) -> np.ndarray:
    """Poses with their headings wrapped (a copy)."""
    out = np.array(poses, dtype=float)
    out[:, 2] = wrap(out[:, 2])
    return out


__all__ = ["LANDMARK_KINDS", "MAX_GAP", "ODOMETRY_FLOOR", "DriveGraph", "drive_graph", "odometry"]
