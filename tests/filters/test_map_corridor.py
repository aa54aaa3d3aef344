"""Seed 004's discrete Bayes filter on the corridor scenario's laser:
``filters/grid/corridor.py``'s CorridorFilter."""

from __future__ import annotations

import math

import numpy as np

from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.core.types import Measurement
from beacon_sim.filters.grid.corridor import walls_seen
from beacon_sim.hosting.loading import build_filter


def test_walls_seen_from_a_scan():
    """Beams at +90 deg (left), -90 deg (right), 0 deg (front): a median under 0.8 m is a wall."""
    rel = np.deg2rad(np.arange(-180, 180, 3.0))
    ranges = np.full(rel.shape, 4.0)
    ranges[np.abs(rel - math.pi / 2) < 0.3] = 0.5           # a wall on the left
    ranges[np.abs(rel) < 0.3] = 0.6                         # and in front
    ranges[np.abs(rel + math.pi / 2) < 0.3] = 1.5           # a door on the right
    ranges[np.argmin(np.abs(rel + math.pi / 2))] = 0.1      # one short reading: the median keeps it a door
    m = Measurement("laser", "range_finder", np.column_stack([ranges, rel]), np.zeros(0, dtype=int))
    assert walls_seen(m, 0.8) == "LF"


def test_the_corridor_filter_follows_the_robot_cell_by_cell():
    """Started lost (uniform over the 20 states), the filter's most likely state is the
    robot's cell and direction, or a neighbouring cell, at every sensing after the first
    door pattern (15 s), and exactly it at most of them; the heat map sums to one."""
    sc = load_scenario("corridor")
    sim = Simulation(sc, seed=4)
    f = build_filter("corridor", sc, 4)
    hits, near, total = 0, 0, 0
    for _ in range(round(120.0 / sc.dt)):
        st = sim.step()
        f.predict(st.control, st.dt)
        pending = f._pending_sense
        f.update(st.measurements)
        if not pending or f._pending_sense or st.time < 15.0:
            continue
        truth, best = f.state_of(st.true_pose), int(np.argmax(f.bel))
        n = f.corridor.n_cells
        same_way = (truth < n) == (best < n)
        total += 1
        hits += truth == best
        near += same_way and abs(truth - best) <= 1
    assert total > 30
    assert near == total
    assert hits / total > 0.6
    bel = f.belief()
    assert bel.prob.shape == (10, 1) and math.isclose(float(bel.prob.sum()), 1.0)
    mean, cov = f.estimate()
    assert abs(mean[0] - st.true_pose[0]) < 1.5 and np.all(np.linalg.eigvalsh(cov) > 0)
