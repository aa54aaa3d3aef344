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


def test_recovery_is_the_first_stretch_below_the_threshold_that_lasts_the_hold():
    err = np.full(20, 0.1)
    err[4:] = [2.0, 1.5, 0.4, 0.7, 0.3, 0.2, 0.2, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1]
    # Kidnap on index 4 (t = 2.5 s); dips below 0.5 at index 6 but goes back up at 7;
    # below for good from index 8 (t = 4.5 s): 2.0 s after the kidnap.
    assert recovery_times(err, TIMES, [4], 0.5, hold=2.0) == [pytest.approx(2.0)]
    # Without a hold the first dip counts (index 6, 1.0 s after the kidnap).
    assert recovery_times(err, TIMES, [4], 0.5, hold=0.0) == [pytest.approx(1.0)]


def test_a_later_excursion_above_the_threshold_does_not_move_the_recovery():
    err = np.full(20, 0.1)
    err[4:9] = 2.0
    err[16] = 0.9  # one bad step long after the hold: the filter had recovered
    assert recovery_times(err, TIMES, [4], 0.5, hold=2.0) == [pytest.approx(2.5)]


def test_two_kidnaps_each_judged_until_the_next():
    err = np.array([0.1] * 3 + [3.0, 0.2, 0.2, 0.2] + [4.0, 4.0, 4.0, 0.9, 0.3] + [0.1] * 8)
    # First kidnap at index 3: below from index 4 to 6 (1.0 s held) -> 0.5 s. Second at
    # index 7: below from index 11 -> 2.0 s.
    assert recovery_times(err, TIMES, [3, 7], 0.5, hold=1.0) == [pytest.approx(0.5),
                                                                 pytest.approx(2.0)]
    # A hold longer than the stretch before the next kidnap: not recovered from the first.
    assert recovery_times(err, TIMES, [3, 7], 0.5, hold=1.5) == [math.inf, pytest.approx(2.0)]


def test_never_recovers_and_already_recovered():
    err = np.array([0.1] * 10 + [2.0] * 9 + [0.1])
    assert recovery_times(err, TIMES, [10], 0.5, hold=0.0) == [pytest.approx(4.5)]
    # Below only on the last step: the hold is cut short by the end of the run.
    assert recovery_times(err, TIMES, [10], 0.5, hold=1.0) == [math.inf]
    err = np.array([0.1] * 10 + [2.0] * 10)
    assert recovery_times(err, TIMES, [10], 0.5) == [math.inf]
    err = np.full(20, 0.1)  # a small kidnap the filter never noticed
    assert recovery_times(err, TIMES, [5], 0.5, hold=2.0) == [0.0]
    err = np.full(20, 0.1)
    err[12:] = np.nan  # a filter that failed before holding: never recovers
    assert recovery_times(err, TIMES, [8], 0.5, hold=3.0) == [math.inf]
    assert recovery_times(err, TIMES, [], 0.5) == []


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_recovery_time_does_not_depend_on_the_length_of_the_run(seed):
    """A synthetic error that falls after a kidnap and then wanders: the recovery computed on
    the first 60 s equals the one on the whole 120 s whenever the 60 s saw it."""
    rng = np.random.default_rng(seed)
    t = 0.1 * np.arange(1, 1201)
    k = 300  # kidnap at 30 s
    err = np.full(t.size, 0.1)
    tau = rng.uniform(3.0, 8.0)
    err[k:] = 2.0 * np.exp(-(t[k:] - t[k]) / tau) + rng.uniform(0.0, 0.3, t.size - k)
    err[900:905] = 0.8  # an excursion at 90-90.5 s, after the shorter run ended
    long = recovery_times(err, t, [k], 0.5)
    short = recovery_times(err[:600], t[:600], [k], 0.5)
    assert math.isfinite(short[0])
    assert short == long


def test_recovery_time_on_krejsa_is_the_same_for_60_s_and_120_s_runs():
    """Seed 000's kidnap at 30 s: each run's recovery (hold 5 s) is the same number whether
    the run lasts 60 s or 120 s whenever the 60 s run saw it, and so is the reported median
    (over all runs, a run not recovered counting as late)."""
    from beacon_sim.core.scenario import load_scenario
    from beacon_sim.evaluation.montecarlo import run_monte_carlo
    from beacon_sim.evaluation.summary import evaluate

    sc = load_scenario("krejsa_bearing_only")
    per, med = {}, {}
    for duration in (60.0, 120.0):
        rs = run_monte_carlo(sc, ["ekf"], 20, seed=0, duration=duration, jobs=1)
        meta, _ = evaluate(sc, rs)
        row = meta["filters"]["ekf"]
        per[duration] = [p["recovery_s"][0] for p in row["per_run"]]
        med[duration] = row["recovery"][0]["median_s"]
    seen = [i for i, v in enumerate(per[60.0]) if v is not None]
    assert len(seen) >= 11  # more than half recover within the 30 s the short run leaves
    for i in seen:
        assert per[60.0][i] == pytest.approx(per[120.0][i], abs=1e-9)
    assert med[60.0] is not None
    assert med[60.0] == pytest.approx(med[120.0], abs=1e-9)
    assert 10.0 < med[120.0] < 35.0


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
