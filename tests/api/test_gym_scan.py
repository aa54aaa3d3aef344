"""The Gymnasium env on a map world: a range finder's block of the observation is a fresh
flag and the scan's ranges (n_beams numbers in [0, max_range]), equal to the step's scan."""

from __future__ import annotations

import warnings

import numpy as np
from gymnasium.utils.env_checker import check_env

from beacon_sim.core.scenario import load_scenario
from beacon_sim.gym import BeaconEnv, observation_names


class LastScans:
    """A reward that records the range-finder scans of each step (and pays nothing)."""

    def __init__(self):
        self.scans: list[np.ndarray | None] = []

    def __call__(self, env, steps):
        found = [m for s in steps for m in s.measurements if m.kind == "range_finder"]
        self.scans.append(found[-1].z[:, 0].copy() if found else None)
        return 0.0


def test_the_observation_holds_the_steps_scan_in_its_box():
    sc = load_scenario("corridor")
    laser = next(s for s in sc.sensors if s.kind == "range_finder")
    reward = LastScans()
    env = BeaconEnv(sc, filters=("dead_reckoning",), reward=reward)
    space = env.observation_space
    assert space.shape == (1 + laser.n_beams,)
    np.testing.assert_array_equal(space.low[1:], 0.0)
    np.testing.assert_array_equal(space.high[1:], np.float32(laser.max_range))
    names = observation_names(sc)
    assert names[0] == f"{laser.name}.fresh" and names[-1] == f"{laser.name}.beam{laser.n_beams - 1}.range_m"
    assert len(names) == space.shape[0]

    obs, _ = env.reset(seed=4)
    assert space.contains(obs) and obs[0] == 0.0           # no scan yet
    rng = np.random.default_rng(0)
    seen_walls = False
    for _ in range(30):
        obs, *_ = env.step(rng.uniform([0.0, -0.5], [0.4, 0.5]))
        assert space.contains(obs)
        scan = reward.scans[-1]
        assert scan is not None and obs[0] == 1.0           # one scan every step by default
        np.testing.assert_array_equal(obs[1:], scan.astype(np.float32))
        seen_walls |= bool(np.any(scan < laser.max_range))
    assert seen_walls   # the corridor's walls are within range: not all beams read max_range
    env.close()


def test_the_scan_env_passes_gymnasiums_checker():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        check_env(BeaconEnv("corridor", filters=("dead_reckoning",)), skip_render_check=True)
