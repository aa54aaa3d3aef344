"""SLAM metrics: the assignment against brute force, GOSPA on hand-built maps (missed and
duplicated landmarks cost c / 2^(1/p) each), ATE, the joint NEES and its band."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from beacon_sim.evaluation.slam_metrics import (
    ate,
    gospa,
    joint_anees_band,
    joint_nees,
    min_cost_assignment,
)


@pytest.mark.parametrize("shape", [(4, 4), (3, 5), (5, 3), (1, 4), (6, 6)])
def test_assignment_is_the_brute_force_minimum(shape):
    rng = np.random.default_rng(sum(shape))
    for _ in range(5):
        C = rng.uniform(0.0, 10.0, shape)
        pairs = min_cost_assignment(C)
        assert len(pairs) == min(shape)
        assert len({i for i, _ in pairs}) == len({j for _, j in pairs}) == min(shape)
        n, m = shape
        if n <= m:
            best = min(sum(C[i, p[i]] for i in range(n)) for p in itertools.permutations(range(m), n))
        else:
            best = min(sum(C[p[j], j] for j in range(m)) for p in itertools.permutations(range(n), m))
        assert sum(C[i, j] for i, j in pairs) == pytest.approx(best)


def test_gospa_of_a_perfect_map_is_zero_and_counts_misses_and_duplicates():
    truth = np.array([[0.0, 0.0], [5.0, 0.0], [0.0, 5.0]])
    assert gospa(truth, truth).value == 0.0
    est = np.array([[0.1, 0.0], [5.0, 0.2]])                  # one beacon missed
    g = gospa(est, truth, c=1.0)
    assert (g.missed, g.false) == (1, 0)
    assert g.value == pytest.approx(math.sqrt(0.01 + 0.04 + 0.5))
    dup = np.vstack([truth, [[0.05, 0.0]]])                   # one beacon mapped twice
    g = gospa(dup, truth, c=1.0)
    assert (g.missed, g.false) == (0, 1) and g.value == pytest.approx(math.sqrt(0.5))
    far = np.array([[0.0, 0.0], [5.0, 0.0], [3.0, 3.0]])      # beyond c: one missed, one false
    g = gospa(far, truth, c=2.0)
    assert (g.missed, g.false) == (1, 1) and g.value == pytest.approx(math.sqrt(4.0))


def test_gospa_of_empty_maps():
    truth = np.array([[0.0, 0.0], [1.0, 1.0]])
    assert gospa(np.zeros((0, 2)), truth, c=2.0).value == pytest.approx(math.sqrt(2 * 2.0))
    assert gospa(np.zeros((0, 2)), np.zeros((0, 2))).value == 0.0
    with pytest.raises(ValueError):
        gospa(truth, truth, c=0.0)


def test_ate_is_the_rms_position_error():
    est = np.array([[0.0, 0.0, 1.0], [1.0, 1.0, 0.0]])
    tru = np.array([[0.3, 0.4, 0.0], [1.0, 1.0, 2.0]])
    assert ate(est, tru) == pytest.approx(math.sqrt(0.25 / 2))


def test_joint_nees_is_the_quadratic_form_with_the_heading_wrapped():
    mean = np.array([1.0, 2.0, math.pi - 0.01, 4.0, 5.0])
    cov = np.diag([0.1, 0.2, 0.01, 0.3, 0.4])
    true_pose = np.array([1.1, 2.0, -math.pi + 0.01])
    v = joint_nees(mean, cov, [7], true_pose, {7: (4.0, 5.2)})
    assert v == pytest.approx(0.01 / 0.1 + 0.02 ** 2 / 0.01 + 0.04 / 0.4)


def test_joint_anees_band_holds_95_percent_of_honest_runs():
    rng = np.random.default_rng(3)
    lo, hi = joint_anees_band(10, 7)
    inside = [lo <= rng.chisquare(7, 10).mean() / 7 <= hi for _ in range(4000)]
    assert 0.93 < np.mean(inside) < 0.97
