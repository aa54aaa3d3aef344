"""The particle filter at rest: no weighting while the command has not moved it
``update_min_d`` or turned it ``update_min_a`` since the last update (AMCL's gate), so a
minute's standstill does not collapse the cloud onto a few poses."""

from __future__ import annotations

import numpy as np

from beacon_sim.core.scenario import load_scenario
from beacon_sim.runs.live import Session


def stand(scenario: str, seed: int, seconds: float, params=None) -> Session:
    sc = load_scenario(scenario)
    s = Session(sc, ["pf"], seed, {"pf": params} if params else None)
    for _ in range(round(seconds / sc.dt)):
        s.tick()
    return s


def test_at_rest_the_particles_are_weighted_once_then_left_alone():
    s = stand("default", 5, 0.2)
    f = s.runner.tracks["pf"].filter
    before = f.belief()
    for _ in range(20):
        s.tick()
    after = f.belief()
    assert np.array_equal(before.poses, after.poses) and np.array_equal(before.weights, after.weights)
    s.drive("w")  # a command that moves: weighted again
    for _ in range(3):
        s.tick()
    assert not np.array_equal(before.weights, f.belief().weights)


def test_nees_stays_in_band_after_a_minute_at_rest():
    """two_rooms, where the ungated filter's NEES passed 10^7 on every seed tried."""
    nees = [stand("two_rooms", seed, 60.0).status["pf"].nees for seed in (3, 4, 5)]
    assert max(nees) < 9.35, nees
    gated_off = stand("two_rooms", 3, 60.0, {"update_min_d": 0.0, "update_min_a": 0.0})
    assert gated_off.status["pf"].nees > 100.0  # what the gate prevents
