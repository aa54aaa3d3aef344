"""The scipy paths (the ``science`` extra) and the numpy paths they replace give the same
results: the distance transform bit for bit, the assignment the same pairs (a unique optimum)
and the same minimum cost (ties)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from beacon_sim.core import beam_model, optional
from beacon_sim.core.beam_model import distance_transform, distance_transform_numpy
from beacon_sim.evaluation.slam_metrics import min_cost_assignment, min_cost_assignment_numpy


@pytest.fixture
def scipy_for_every_size(monkeypatch):
    monkeypatch.setattr(beam_model, "SCIPY_MIN_CELLS", 0)


@pytest.mark.parametrize("seed", range(4))
def test_distance_transforms_are_equal_bit_for_bit(seed, scipy_for_every_size):
    rng = np.random.default_rng(seed)
    for shape, density in (((40, 57), 0.02), ((1, 30), 0.1), ((31, 1), 0.1), ((120, 90), 0.002),
                           ((64, 64), 0.5)):
        occ = rng.random(shape) < density
        occ[rng.integers(shape[0]), rng.integers(shape[1])] = True
        want = distance_transform_numpy(occ)
        np.testing.assert_array_equal(distance_transform(occ), want)
        for cap in (0.5, 3.0, 7.25):
            np.testing.assert_array_equal(distance_transform(occ, cap), distance_transform_numpy(occ, cap))


def test_distance_transform_edge_cases_both_ways(scipy_for_every_size):
    for occ in (np.zeros((3, 4), dtype=bool), np.ones((3, 4), dtype=bool)):
        for cap in (None, 2.0):
            np.testing.assert_array_equal(distance_transform(occ, cap), distance_transform_numpy(occ, cap))


def test_without_scipy_the_numpy_path_runs(monkeypatch, scipy_for_every_size):
    monkeypatch.setitem(optional._FOUND, "scipy.ndimage", None)
    occ = np.zeros((5, 5), dtype=bool)
    occ[2, 2] = True
    assert distance_transform(occ)[0, 0] == np.sqrt(8.0)


def brute_force(cost: np.ndarray) -> float:
    n, m = cost.shape
    if n <= m:
        return min(sum(cost[i, c] for i, c in enumerate(p)) for p in itertools.permutations(range(m), n))
    return brute_force(cost.T)


@pytest.mark.parametrize("shape", [(1, 1), (3, 3), (4, 6), (6, 4), (5, 5), (2, 7)])
def test_assignments_are_equal_and_optimal(shape):
    rng = np.random.default_rng(sum(shape))
    for _ in range(5):
        cost = rng.random(shape)
        a, b = min_cost_assignment(cost), min_cost_assignment_numpy(cost)
        assert a == b and len(a) == min(shape)
        assert sum(cost[i, j] for i, j in a) == pytest.approx(brute_force(cost), abs=1e-12)


def test_ties_reach_the_same_cost():
    rng = np.random.default_rng(5)
    cost = rng.integers(0, 3, size=(6, 6)).astype(float)  # many optima
    a, b = min_cost_assignment(cost), min_cost_assignment_numpy(cost)
    assert sum(cost[i, j] for i, j in a) == sum(cost[i, j] for i, j in b) == brute_force(cost)


def test_without_scipy_or_with_infinite_costs_the_numpy_path_runs(monkeypatch):
    cost = np.array([[1.0, np.inf], [0.5, 2.0]])
    assert min_cost_assignment(cost) == min_cost_assignment_numpy(cost) == [(0, 0), (1, 1)]
    monkeypatch.setitem(optional._FOUND, "scipy.optimize", None)
    assert min_cost_assignment(np.array([[3.0, 1.0], [1.0, 3.0]])) == [(0, 1), (1, 0)]
    assert min_cost_assignment(np.zeros((0, 3))) == []
