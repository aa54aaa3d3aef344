"""Seed 004's corridor against values computed by hand (in units of 1/26 and 1/24)."""

import numpy as np
import pytest

from beacon_sim.filters.grid.corridor import Corridor


def test_layout_of_the_corridor():
    c = Corridor()                       # north doors at cells 2, 6; south door at 4
    assert c.layout(9) == "LRF"          # seed 004: x_9 is LRF (end of the corridor)
    assert c.layout(10) == "LR"          # state 10 is cell 9 facing -x: open corridor ahead
    assert c.layout(19) == "LRF"         # cell 0 facing -x has the wall in front
    assert c.layout(2) == "R"            # door on the left (north) when facing +x
    assert c.layout(4) == "L"            # door on the right (south)
    assert c.layout(19 - 4) == "R"       # cell 4 facing -x: the south door is on the left
    assert c.layout(3) == "LR"


def test_sense_move_sense_by_hand():
    c = Corridor()
    bel = c.uniform()
    assert bel == pytest.approx(np.full(20, 0.05))
    # Reading "R" matches states 2, 6 (facing +x) and 15 (cell 4 facing -x).
    # Unnormalised: 3 states x 0.05 x 0.6 = 0.09, 17 x 0.05 x 0.2 = 0.17; total 0.26.
    bel = c.sense(bel, "R")
    expect = np.full(20, 1 / 26)
    expect[[2, 6, 15]] = 3 / 26
    assert bel == pytest.approx(expect)
    # Forward: cell 3 gets 0.8 p(2) + 0.1 p(1) + 0.1 p(3) = (2.4 + 0.1 + 0.1) / 26 = 2.6 / 26.
    # Lost over the ends: state 9 loses 0.9, state 8 loses 0.1 (same for 19 and 18), each
    # with mass 1/26: total 2 / 26, so the normaliser is 24 / 26.
    bel = c.forward(bel)
    assert bel[3] == pytest.approx(2.6 / 24)
    assert bel[0] == pytest.approx(0.1 / 24)                 # nothing arrives at the start
    assert bel[1] == pytest.approx((0.8 + 0.1) / 24)          # from state 0 and itself
    assert bel[4] == pytest.approx((0.8 + 0.3 + 0.1) / 24)    # 0.8 p3 + 0.1 p2 + 0.1 p4
    assert bel[7] == pytest.approx((2.4 + 0.1 + 0.1) / 24)    # 0.8 p6 + 0.1 p5 + 0.1 p7
    assert bel[16] == pytest.approx((2.4 + 0.1 + 0.1) / 24)   # 0.8 p15 + 0.1 p14 + 0.1 p16
    assert bel.sum() == pytest.approx(1.0)


def test_turn_by_hand():
    c = Corridor()
    bel = np.zeros(20)
    bel[3] = 1.0
    out = c.turn(bel)
    assert out[16] == pytest.approx(0.9)   # N - 1 - 3 = 16: same cell, other direction
    assert out[3] == pytest.approx(0.1)
    assert out.sum() == pytest.approx(1.0)


def test_repeated_sensing_concentrates_on_the_end():
    # Two "LRF" readings: factor (0.6 / 0.2)^2 = 9 for states 9 and 19 over the other 18.
    c = Corridor()
    bel = c.sense(c.sense(c.uniform(), "FRL"), "LRF")
    assert bel[9] == pytest.approx(9 / (2 * 9 + 18))
    assert bel[19] == pytest.approx(9 / 36)
    assert bel[0] == pytest.approx(1 / 36)
