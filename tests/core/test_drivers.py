import numpy as np
import pytest
from helpers import make_scenario

from beacon_sim.core.keyboard_drive import KeyboardDrive, KeyboardLimits
from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.simulation import Simulation


def test_keyboard_steps_limits_and_stop():
    k = KeyboardDrive(KeyboardLimits(v_step=0.1, v_max=0.3, v_min=-0.2, omega_step=0.5, omega_max=1.0))
    for _ in range(5):
        k.press("w")
    assert k.v == pytest.approx(0.3)  # clamped at v_max
    k.press("s")
    assert k.v == pytest.approx(0.2)
    k.press("a")
    assert k.omega == pytest.approx(0.5)  # A steers left: omega up (counter-clockwise)
    k.press("d")
    k.press("d")
    k.press("D")
    assert k.omega == pytest.approx(-1.0)  # clamped at -omega_max
    for _ in range(10):
        k.press("s")
    assert k.v == pytest.approx(-0.2)
    assert k.press("x") and k.v == 0.0 and k.omega == 0.0
    assert not k.press("q")


def test_circle_driver_closes_a_circle():
    sc = make_scenario(driver={"kind": "circle", "radius": 2.0, "speed": 0.5},
                       robot={"initial_pose": [5.0, 3.0, 0.0]})
    sc = sc.with_changes(motion_noise=type(sc.motion_noise)())
    steps = Simulation(sc, 0).run(2 * np.pi * 2.0 / 0.5)
    # Euler integration drifts slightly outward; after one lap the robot is back near start.
    assert np.hypot(*(steps[-1].true_pose[:2] - [5.0, 3.0])) < 0.2
    assert max(s.true_pose[1] for s in steps) == pytest.approx(7.0, abs=0.15)


def test_random_goal_planner_reaches_goals_inside_the_margin():
    sc = load_scenario("krejsa_bearing_only")
    sim = Simulation(sc, 3)
    goals = set()
    for _ in range(1200):
        sim.step()
        goals.add(tuple(sim.driver.goal))
    assert len(goals) >= 3  # it reached goals and drew new ones
    g = np.array(sorted(goals))
    assert g.min() >= 1.0 and g.max() <= 9.0


def test_waypoints_are_visited_in_order():
    sc = make_scenario(driver={"kind": "waypoints", "points": [[7.0, 5.0], [7.0, 8.0]],
                               "loop": False, "speed": 0.5})
    sim = Simulation(sc, 0)
    steps = sim.run(40.0)
    d1 = [np.hypot(*(s.true_pose[:2] - [7.0, 5.0])) for s in steps]
    d2 = [np.hypot(*(s.true_pose[:2] - [7.0, 8.0])) for s in steps]
    assert int(np.argmin(d1)) < int(np.argmin(d2)) and min(d2) < 0.25
    assert steps[-1].control.v == 0.0  # stops after the last point without looping
