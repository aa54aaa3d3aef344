"""The panel's NEES badge: a verdict on the mean NEES of the last NEES_WINDOW_S seconds
against its chi-square band, in both directions, none before the window is full (dead
reckoning started on the truth is not flagged at t = 0), rare on a consistent filter."""

from __future__ import annotations

import math

import numpy as np
import pytest

from beacon_sim.core.scenario import load_scenario
from beacon_sim.runs.live import Session
from beacon_sim.runs.nees_alarm import count_alarms
from beacon_sim.runs.scene import NEES_WINDOW_BAND, NEES_WINDOW_S, FilterStatus

DT = 0.05
K = round(NEES_WINDOW_S / DT)


def feed(st: FilterStatus, sigmas_off: float, n: int, rng: np.random.Generator) -> None:
    """n estimates of a filter claiming cov = I*0.01 whose error is ``sigmas_off`` times
    that (0: exact; 1: consistent)."""
    cov = np.eye(3) * 0.01
    for _ in range(n):
        e = rng.normal(size=3) * 0.1 * sigmas_off
        st.measure(e, cov, np.zeros(3), DT)


def test_no_verdict_before_the_window_is_full_then_both_directions():
    rng = np.random.default_rng(1)
    exact, wild, fair = FilterStatus("exact"), FilterStatus("wild"), FilterStatus("fair")
    feed(exact, 0.0, K - 1, rng)
    feed(wild, 4.0, K - 1, rng)
    assert exact.nees == 0.0 and exact.nees_verdict is None and math.isnan(exact.nees_mean)
    assert wild.nees > NEES_WINDOW_BAND[1] and wild.nees_verdict is None
    feed(exact, 0.0, 1, rng)
    feed(wild, 4.0, 1, rng)
    feed(fair, 1.0, K, rng)
    assert exact.nees_verdict == "low" and exact.nees_out_of_band
    assert wild.nees_verdict == "high"
    assert fair.nees_verdict is None and NEES_WINDOW_BAND[0] < fair.nees_mean < NEES_WINDOW_BAND[1]
    wild.clear_window()  # a reset: judged afresh
    assert wild.nees_verdict is None


def test_dead_reckoning_on_the_truth_has_no_badge_at_the_start():
    s = Session(load_scenario("default"), ["ekf", "dead_reckoning"])
    for _ in range(20):
        s.tick()
        st = s.status["dead_reckoning"]
        assert st.nees < NEES_WINDOW_BAND[0]  # the tick's NEES alone would flag it
        assert not st.nees_out_of_band


def test_a_reset_clears_the_window():
    s = Session(load_scenario("default"), ["ekf"])
    for _ in range(K):
        s.tick()
    assert not math.isnan(s.status["ekf"].nees_mean)
    s.command({"kind": "reset"})
    s.tick()
    assert math.isnan(s.status["ekf"].nees_mean)


@pytest.mark.parametrize("seed", [11])
def test_a_consistent_ekf_raises_few_alarms(seed):
    """Ten minutes of driving: the per-tick band flags a consistent EKF dozens of times,
    the window's verdict at most a couple (measured: about 2 an hour)."""
    c = count_alarms(load_scenario("default"), "ekf", seed, 600.0)
    assert c.per_tick > 40
    assert c.windowed <= 2
