import math

import numpy as np
import pytest
from helpers import make_scenario

from beacon_sim.core.events import first_tick_at
from beacon_sim.core.simulation import Simulation
from beacon_sim.core.types import Control


def test_first_tick_at_or_after():
    assert first_tick_at(1.0, 0.1) == 10  # 10 * 0.1 == 1.0 despite rounding
    assert first_tick_at(1.01, 0.1) == 11
    assert first_tick_at(0.0, 0.1) == 1


def test_absolute_kidnap_fires_on_the_right_tick():
    sc = make_scenario(events=[{"kind": "kidnap", "time": 2.05, "pose": [1.0, 2.0, 3.0]}])
    sim = Simulation(sc, seed=1)
    steps = sim.run(3.0)
    fired = [s.tick for s in steps if s.kidnapped]
    assert fired == [21]
    s = steps[20]
    assert np.allclose(s.true_pose, [1.0, 2.0, 3.0])
    assert np.allclose(s.events[0].pose_after, [1.0, 2.0, 3.0])


def test_relative_kidnap_is_seed_000s_displacement():
    off = [1.0, 0.5, -math.pi / 2]
    sc = make_scenario(events=[{"kind": "kidnap", "time": 1.0, "offset": off}])
    steps = Simulation(sc, seed=4).run(1.5)
    ev = steps[9].events[0]
    assert steps[9].tick == 10
    delta = ev.pose_after - ev.pose_before
    assert delta[:2] == pytest.approx([1.0, 0.5])
    assert math.remainder(delta[2] + math.pi / 2, 2 * math.pi) == pytest.approx(0.0, abs=1e-12)


def test_random_kidnap_lands_in_bounds_and_is_reproducible():
    sc = make_scenario(events=[{"kind": "kidnap", "time": 0.5, "random": True}])
    a = Simulation(sc, seed=11).run(1.0)[4]
    b = Simulation(sc, seed=11).run(1.0)[4]
    c = Simulation(sc, seed=12).run(1.0)[4]
    assert a.kidnapped and np.array_equal(a.true_pose, b.true_pose)
    assert not np.array_equal(a.true_pose, c.true_pose)
    assert 0 <= a.true_pose[0] <= 10 and 0 <= a.true_pose[1] <= 10


def test_blackout_silences_the_sensor_for_its_interval():
    sc = make_scenario(events=[{"kind": "blackout", "time": 1.0, "duration": 0.5}])
    steps = Simulation(sc, seed=1).run(2.0)
    silent = [s.tick for s in steps if not s.measurements]
    assert silent == [10, 11, 12, 13, 14]
    kinds = {e.kind: e.tick for s in steps for e in s.events}
    assert kinds == {"blackout_start": 10, "blackout_end": 15}


def test_noise_burst_disturbs_the_truth_only_during_the_burst():
    quiet = make_scenario(robot={"initial_pose": [5.0, 5.0, 0.0]})
    burst = make_scenario(robot={"initial_pose": [5.0, 5.0, 0.0]},
                          events=[{"kind": "noise_burst", "time": 1.0, "duration": 1.0, "v_std": 0.5}])
    a = Simulation(quiet, seed=2).run(3.0)
    b = Simulation(burst, seed=2).run(3.0)
    assert all(np.array_equal(x.true_pose, y.true_pose) for x, y in zip(a[:9], b[:9], strict=True))
    assert not np.array_equal(a[15].true_pose, b[15].true_pose)


def test_user_kidnap_request_applies_on_the_next_step():
    sim = Simulation(make_scenario(), seed=0)
    sim.step(Control(0.1, 0.0))
    sim.request_kidnap([3.0, 4.0, 1.0])
    s = sim.step(Control(0.1, 0.0))
    assert s.kidnapped and np.allclose(s.true_pose, [3.0, 4.0, 1.0])
    assert not sim.step(Control(0.1, 0.0)).kidnapped
