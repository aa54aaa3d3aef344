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


def feed_at(st: FilterStatus, nees: float, n: int, moving: bool, start: int = 0) -> None:
    """n estimates whose NEES is ``nees`` exactly, the truth still or moving 1 cm a tick."""
    cov = np.eye(3) * 0.01
    e = np.array([math.sqrt(nees * 0.01), 0.0, 0.0])
    for k in range(start, start + n):
        truth = np.array([0.01 * k if moving else 0.0, 0.0, 0.0])
        st.measure(truth + e, cov, truth, DT)


def test_a_window_at_rest_counts_as_one_value_so_a_steady_nees_is_judged_as_one():
    """A NEES of 0.5 on every tick: while the robot moves, twenty seconds of it are ten
    independent values far below their band ("low"); at rest they are one value, inside the
    band of one. A NEES of 50 at rest is out of even that band ("high")."""
    moving, still, wild = FilterStatus("moving"), FilterStatus("still"), FilterStatus("wild")
    feed_at(moving, 0.5, K, moving=True)
    feed_at(still, 0.5, K, moving=False)
    feed_at(wild, 50.0, K, moving=False)
    assert moving.nees_samples == pytest.approx(10.0) and moving.nees_verdict == "low"
    # (the first tick has no tick before it: it counts as moved)
    assert still.nees_samples == pytest.approx(K * K / (K / 10 + (K - 1) ** 2))
    assert still.nees_samples < 1.01 and still.nees_verdict is None
    assert wild.nees_verdict == "high"


def test_the_windows_worth_is_kishs_effective_size_of_its_moving_ticks_and_rests():
    """Half the window moving (five values' worth, a tenth each), half one rest (one value of
    half the weight): 1 / (5 * 0.1^2 + 0.5^2) = 3.33 (3.36: the rest's first tick moved from
    the tick before); as the rest leaves the window the worth climbs back to ten."""
    st = FilterStatus("ekf")
    feed_at(st, 3.0, K // 2, moving=True)
    feed_at(st, 3.0, K // 2, moving=False)
    moved, rest = K // 2 + 1, K // 2 - 1
    assert st.nees_samples == pytest.approx(K * K / (moved * K / 10 + rest**2))
    assert abs(st.nees_samples - 1 / (5 * 0.01 + 0.25)) < 0.03
    feed_at(st, 3.0, K, moving=True, start=K)
    assert st.nees_samples == pytest.approx(10.0)
    st.clear_window()
    assert math.isnan(st.nees_samples) and st.nees_verdict is None


def test_a_pause_puts_no_badge_on_a_consistent_filter_and_one_on_a_filter_that_is_not():
    """A minute's standstill (the window's session, the keyboard never pressed), unseen
    seeds: the EKF on default got a badge on 14 of 20 seeds with the window judged as ten
    values; none now. The particle filter weighing every tick's readings on particles that
    cannot move (its rest gate off: docs/results.md) is still flagged."""
    from beacon_sim.runs.nees_alarm import count_standstill_badges

    ekf = count_standstill_badges(load_scenario("default"), "ekf", range(20000, 20010), 60.0)
    assert ekf.ticks == 10 * (1200 - K + 1)
    assert ekf.flagged == 0
    off = {"pf": {"update_min_d": 0.0, "update_min_a": 0.0, "n_particles": 500}}
    pf = count_standstill_badges(load_scenario("two_rooms"), "pf", range(20000, 20005), 60.0, off)
    assert pf.flagged >= 4 and pf.high > 0
