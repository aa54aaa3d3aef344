"""Recovery time after a kidnap, divergence and NIS on hand-made numbers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from beacon_sim.core.sensors import SensorNoise, SensorSpec
from beacon_sim.core.types import Beacon, Measurement
from beacon_sim.core.world import World
from beacon_sim.evaluation.metrics import diverged, nis, recovery_times

DT = 0.5
TIMES = DT * np.arange(1, 21)  # steps 1..20 at 0.5 s


def test_recovery_is_the_last_crossing_below_the_threshold():
    err = np.full(20, 0.1)
    err[4:] = [2.0, 1.5, 0.4, 0.7, 0.3, 0.2, 0.2, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1]
    # Kidnap on index 4 (t = 2.5 s); dips below 0.5 at index 6 but goes back up at 7;
    # below for good from index 8 (t = 4.5 s): 2.0 s after the kidnap.
    assert recovery_times(err, TIMES, [4], 0.5) == [pytest.approx(2.0)]


def test_two_kidnaps_each_judged_until_the_next():
    err = np.array([0.1] * 3 + [3.0, 0.2, 0.2, 0.2] + [4.0, 4.0, 4.0, 0.9, 0.3] + [0.1] * 8)
    # First kidnap at index 3: below from index 4 -> 0.5 s. Second at index 7: below from
    # index 11 -> 2.0 s.
    assert recovery_times(err, TIMES, [3, 7], 0.5) == [pytest.approx(0.5), pytest.approx(2.0)]


def test_never_recovers_and_already_recovered():
    err = np.array([0.1] * 10 + [2.0] * 9 + [0.1])
    assert recovery_times(err, TIMES, [10], 0.5) == [pytest.approx(4.5)]
    err = np.array([0.1] * 10 + [2.0] * 10)
    assert recovery_times(err, TIMES, [10], 0.5) == [math.inf]
    err = np.full(20, 0.1)  # a small kidnap the filter never noticed
    assert recovery_times(err, TIMES, [5], 0.5) == [0.0]
    err = np.full(20, 0.1)
    err[12:] = np.nan  # a filter that failed never recovers
    assert recovery_times(err, TIMES, [5], 0.5) == [math.inf]
    assert recovery_times(err, TIMES, [], 0.5) == []


def test_divergence_needs_the_whole_tail_above_the_threshold():
    err = np.linspace(0.0, 3.0, 100)
    assert diverged(err, 1.0)
    err[-1] = 0.5  # back below on the last step: not lost
    assert not diverged(err, 1.0)
    assert not diverged(np.full(50, 0.2), 1.0)
    assert diverged(np.r_[np.full(50, 0.2), np.full(10, np.nan)], 1.0)


def test_nis_of_a_pose_fix_by_hand():
    world = World((0.0, 0.0, 10.0, 10.0), (Beacon(1, 1.0, 1.0), Beacon(2, 2.0, 1.0)))
    spec = SensorSpec("fix", "pose", noise=SensorNoise(position_std=0.2, heading_std=0.1))
    mean = np.array([1.0, 2.0, 3.1])
    P = np.diag([0.01, 0.04, 0.02])
    # Two beacons: R = diag(0.04, 0.04, 0.01) / 2. Heading residual wraps: -3.1 - 3.1 + 2 pi.
    z = np.array([[1.3, 1.8, -3.1]])
    m = Measurement("fix", "pose", z, np.array([1, 2]))
    value, dof = nis([m], {"fix": spec}, mean, P, world)
    dth = -3.1 - 3.1 + 2 * math.pi
    expected = 0.3**2 / 0.03 + 0.2**2 / 0.06 + dth**2 / 0.025
    assert dof == 3
    assert value == pytest.approx(expected, rel=1e-12)
