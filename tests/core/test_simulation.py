import numpy as np
from helpers import make_scenario

from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.core.streams import filter_stream
from beacon_sim.core.types import Control


def truth(steps):
    return np.array([s.true_pose for s in steps])


def all_measurements(steps):
    return [(s.tick, m.sensor, m.z.tobytes(), m.beacon_ids.tobytes()) for s in steps
            for m in s.measurements]


def test_same_seed_same_arrays_bit_for_bit():
    sc = load_scenario("krejsa_bearing_only")
    a, b = Simulation(sc, 5).run(20.0), Simulation(sc, 5).run(20.0)
    assert np.array_equal(truth(a), truth(b))
    assert all_measurements(a) == all_measurements(b)
    c = Simulation(sc, 6).run(20.0)
    assert not np.array_equal(truth(a), truth(c))


def test_checksum_identifies_the_trajectory():
    sc = make_scenario()
    s1, s2, s3 = Simulation(sc, 1), Simulation(sc, 1), Simulation(sc, 2)
    for s in (s1, s2, s3):
        s.run(5.0)
    assert s1.truth_checksum == s2.truth_checksum != s3.truth_checksum


def test_global_and_other_streams_leave_the_truth_unchanged():
    sc = make_scenario()
    np.random.seed(1)
    a = Simulation(sc, 3).run(5.0)
    np.random.seed(2)
    sim = Simulation(sc, 3)
    other = filter_stream(3, "pf")  # a filter drawing from its own stream
    b = []
    for _ in range(50):
        np.random.random(100)
        other.random(1000)
        b.append(sim.step())
    assert np.array_equal(truth(a), truth(b))
    assert all_measurements(a) == all_measurements(b)


def test_adding_a_sensor_does_not_change_the_truth_or_other_sensors():
    base = make_scenario()
    more = make_scenario(sensors=[
        {"name": "rb", "kind": "range_bearing", "max_range": 20.0, "range_std": 0.1,
         "bearing_std": 0.05},
        {"name": "fix", "kind": "pose", "position_std": 0.1}])
    a, b = Simulation(base, 9).run(5.0), Simulation(more, 9).run(5.0)
    assert np.array_equal(truth(a), truth(b))
    rb_b = [x for x in all_measurements(b) if x[1] == "rb"]
    assert all_measurements(a) == rb_b


def test_controls_given_explicitly_equal_driver_controls():
    sc = make_scenario()
    a = Simulation(sc, 1).run(3.0)
    b = Simulation(sc, 1).run(3.0, controls=[Control(0.2, 0.1)] * 30)
    assert np.array_equal(truth(a), truth(b))


def test_sensor_period_in_ticks():
    sc = make_scenario(sensors=[{"name": "rb", "kind": "range_bearing", "period": 0.3}])
    ticks = [s.tick for s in Simulation(sc, 0).run(1.5) if s.measurements]
    assert ticks == [3, 6, 9, 12, 15]


def test_truth_stays_inside_the_walls():
    sc = make_scenario(driver={"kind": "constant", "v": 1.0, "omega": 0.0})
    steps = Simulation(sc, 0).run(20.0)
    assert truth(steps)[:, 0].max() <= 10.0
