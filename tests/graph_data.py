"""Where the tests find the g2o graphs (never committed: ../shared/data/graphs beside the
checkout, or the folder in BEACON_SIM_GRAPHS); a test skips with the reason when absent."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from beacon_sim.filters.graph import EdgeSet, FactorGraph
from beacon_sim.filters.graph.se2 import between, compose

GRAPHS_VARIABLE = "BEACON_SIM_GRAPHS"
ROOT = Path(__file__).resolve().parent.parent


def graph_file(name: str) -> Path:
    """The path of graph ``name`` (e.g. ``intel.g2o``), or skip the test saying where it was looked for."""
    where = os.environ.get(GRAPHS_VARIABLE)
    folder = Path(where) if where else ROOT.parent / "shared" / "data" / "graphs"
    path = folder / name
    if not path.is_file():
        pytest.skip(f"{name} not found in {folder} (set {GRAPHS_VARIABLE} to the folder of the g2o graphs)")
    return path


def synthetic_graph(seed: int = 5, n: int = 30, m: int = 6) -> tuple[FactorGraph, np.ndarray, np.ndarray]:
    """A square drive with odometry, a loop closure and range-bearing landmark edges, the
    measurements noisy, the initial values perturbed; returns it and the true nodes."""
    rng = np.random.default_rng(seed)
    steps = np.tile([[0.5, 0.0, 2 * np.pi / n]], (n - 1, 1))
    truth = [np.zeros(3)]
    for s in steps:
        truth.append(compose(truth[-1], s))
    P = np.array(truth)
    L = rng.uniform(-1, 4, (m, 2))
    so = np.array([0.02, 0.02, 0.01])
    z_odo = between(P[:-1], P[1:]) + rng.normal(size=(n - 1, 3)) * so
    z_loop = between(P[-1:], P[:1]) + rng.normal(size=(1, 3)) * so
    pi, lj = np.repeat(np.arange(n), m), np.tile(np.arange(m), n)
    d = L[lj] - P[pi, :2]
    z_rb = np.column_stack([np.hypot(d[:, 0], d[:, 1]), np.arctan2(d[:, 1], d[:, 0]) - P[pi, 2]])
    z_rb += rng.normal(size=z_rb.shape) * [0.05, 0.02]
    z_rb[:, 1] = (z_rb[:, 1] + np.pi) % (2 * np.pi) - np.pi
    edges = [EdgeSet("pose", "odometry", np.arange(n - 1), np.arange(1, n), z_odo,
                     np.tile(np.diag(1 / so**2), (n - 1, 1, 1))),
             EdgeSet("pose", "loop closure", [n - 1], [0], z_loop, np.diag(1 / so**2)[None]),
             EdgeSet("range_bearing", "landmark", pi, lj, z_rb,
                     np.tile(np.diag([1 / 0.05**2, 1 / 0.02**2]), (n * m, 1, 1)))]
    init_P = P + rng.normal(size=P.shape) * [0.1, 0.1, 0.05]
    init_P[0] = P[0]
    return FactorGraph(init_P, L + rng.normal(size=L.shape) * 0.2, edges), P, L
