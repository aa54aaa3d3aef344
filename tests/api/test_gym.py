"""The Gymnasium environment (beacon_sim.gym): Gymnasium's own checker, seeded determinism,
the observation encoding, the shipped reward, rendering by the window's renderer, and pygame
left unimported while nothing is drawn."""

from __future__ import annotations

import math
import os
import subprocess
import sys
import types
import warnings
from pathlib import Path

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import beacon_sim as bs
from beacon_sim.core.types import Measurement
from beacon_sim.gym import ENV_ID, BeaconEnv, neg_log_det, observation_names

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def test_check_env_passes():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # advice (e.g. normalise the action), not failures
        check_env(BeaconEnv("default", ["ekf"]), skip_render_check=True)
        env = gymnasium.make(ENV_ID, scenario="sparse_kidnap", filters=["ekf", "pf"],
                             params={"pf": {"n_particles": 200}}, render_mode="rgb_array")
        check_env(env.unwrapped)  # with the render check


def rollout(seed: int, n: int = 60, scenario: str = "sparse_kidnap"):
    env = BeaconEnv(scenario, ["ekf", "pf"], params={"pf": {"n_particles": 200}})
    env.action_space.seed(seed)
    obs, info = env.reset(seed=seed)
    out, rewards, poses = [obs], [], [info["true_pose"]]
    for _ in range(n):
        obs, r, term, trunc, info = env.step(env.action_space.sample())
        out.append(obs)
        rewards.append(r)
        poses.append(np.concatenate([info["true_pose"], info["estimate"], info["cov"].ravel()]))
        assert not term and not trunc
    return np.array(out), np.array(rewards), poses


def test_a_seeded_rollout_is_deterministic_bit_for_bit():
    a, ra, pa = rollout(7)
    b, rb, pb = rollout(7)
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(ra, rb)
    for x, y in zip(pa, pb, strict=True):
        np.testing.assert_array_equal(x, y)
    _, rc, _ = rollout(8)
    assert not np.array_equal(rc, ra)  # and the seed matters


def test_reset_with_the_same_seed_replays_the_episode_in_the_same_env():
    env = BeaconEnv("default", ["ekf"])
    runs = []
    for _ in range(2):
        env.reset(seed=3)
        runs.append([env.step(np.array([0.5, 0.4], dtype=np.float32))[1] for _ in range(30)])
    assert runs[0] == runs[1]


def test_the_reward_is_minus_the_log_determinant_of_the_chosen_filter():
    env = BeaconEnv("default", ["dead_reckoning", "ekf"], reward=neg_log_det("ekf"), tracked="ekf")
    env.reset(seed=1)
    for _ in range(5):
        _, r, _, _, info = env.step(np.array([0.3, 0.0], dtype=np.float32))
        _, cov = env.estimate("ekf")
        assert r == pytest.approx(-math.log(np.linalg.det(cov)), rel=1e-12)
        np.testing.assert_array_equal(info["cov"], cov)
    _, dr_cov = env.estimate("dead_reckoning")
    assert r > -math.log(np.linalg.det(dr_cov))  # the EKF is surer than dead reckoning


def test_a_custom_reward_gets_the_env_and_the_steps():
    seen = []

    def reward(env, steps):
        seen.append([s.tick for s in steps])
        return float(len(steps))

    env = BeaconEnv("default", ["ekf"], reward=reward)
    env.reset(seed=0)
    assert env.step(env.action_space.sample())[1] == env.ticks_per_step == 2  # 10 Hz sensor, 20 Hz ticks
    env.step(env.action_space.sample())
    assert seen == [[1, 2], [3, 4]]


def test_the_observation_encodes_each_beacon_in_its_slot():
    env = BeaconEnv("default", ["ekf"])
    env.reset(seed=0)
    names = observation_names(env.scenario)
    assert len(names) == env.observation_space.shape[0] == 7 * 4
    assert names[8:12] == ["beacons.B3.seen", "beacons.B3.range_m", "beacons.B3.cos_bearing",
                           "beacons.B3.sin_bearing"]
    m = Measurement("beacons", "range_bearing", np.array([[2.0, 0.5], [1.5, -1.0]]), np.array([3, 7]))
    step = types.SimpleNamespace(measurements=(m,))
    obs = env.encode([step])
    np.testing.assert_allclose(obs[8:12], [1.0, 2.0, math.cos(0.5), math.sin(0.5)], rtol=1e-6)
    np.testing.assert_allclose(obs[24:28], [1.0, 1.5, math.cos(-1.0), math.sin(-1.0)], rtol=1e-6)
    assert np.count_nonzero(obs) == 8
    assert env.observation_space.contains(obs)


def test_observations_of_a_real_episode_hold_its_readings():
    env = BeaconEnv("default", ["ekf"])
    env.reset(seed=4)
    for _ in range(10):
        obs, *_ = env.step(np.array([0.4, 0.0], dtype=np.float32))
        assert env.observation_space.contains(obs)
        m = env.session.last_step.steps[0].measurements  # the step's second tick is a sensor tick
        seen = {int(b) for mm in m for b in mm.beacon_ids}
        ids = [b.id for b in env.scenario.world.beacons]
        assert {ids[k] for k in range(len(ids)) if obs[4 * k] == 1.0} == seen


def test_a_failing_tracked_filter_ends_the_episode():
    class Breaks(bs.FilterBase):
        def reset(self, initial):
            self.m, self.c = initial.mean.copy(), initial.cov.copy()

        def predict(self, control, dt):
            raise RuntimeError("no")

        def update(self, measurements):
            pass

        def estimate(self):
            return self.m, self.c

    mod = types.ModuleType("beacon_sim_test_breaks")
    mod.Breaks = Breaks
    sys.modules[mod.__name__] = mod
    try:
        env = BeaconEnv("default", ["beacon_sim_test_breaks:Breaks"], failed_penalty=7.0)
        env.reset(seed=0)
        _, r, terminated, truncated, _ = env.step(np.zeros(2, dtype=np.float32))
        assert (r, terminated, truncated) == (-7.0, True, False)
    finally:
        del sys.modules[mod.__name__]


def test_truncated_after_max_steps():
    env = BeaconEnv("default", ["ekf"], max_steps=3)
    env.reset(seed=0)
    flags = [env.step(np.zeros(2, dtype=np.float32))[3] for _ in range(3)]
    assert flags == [False, False, True]


def _frame(seed: int):
    env = BeaconEnv("default", ["ekf"], render_mode="rgb_array", size=(320, 220))
    env.reset(seed=seed)
    for _ in range(10):
        env.step(np.array([0.5, 0.2], dtype=np.float32))
    frame = env.render()
    env.close()
    return frame


def test_rgb_array_is_the_windows_drawing():
    frame = _frame(2)
    assert frame.shape == (220, 320, 3) and frame.dtype == np.uint8
    assert len(np.unique(frame.reshape(-1, 3), axis=0)) > 20  # a drawing, not a blank surface
    np.testing.assert_array_equal(_frame(2), frame)


def test_human_mode_draws_into_a_window():
    env = BeaconEnv("default", ["ekf"], render_mode="human", size=(320, 220))
    env.reset(seed=0)
    env.step(np.zeros(2, dtype=np.float32))
    assert env.render() is None
    env.close()


def test_pygame_is_imported_only_to_draw():
    code = """
import sys, numpy as np
from beacon_sim.gym import BeaconEnv
env = BeaconEnv("default", ["ekf"], render_mode="rgb_array")
env.reset(seed=0)
for _ in range(5):
    env.step(np.zeros(2, dtype=np.float32))
assert "pygame" not in sys.modules
env.render()
assert "pygame" in sys.modules
print("ok")
"""
    env = {**os.environ, "SDL_VIDEODRIVER": "dummy", "SDL_AUDIODRIVER": "dummy"}
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, env=env)
    assert r.returncode == 0 and r.stdout.strip() == "ok", r.stderr[-2000:]


def test_the_example_runs_and_greedy_beats_random():
    sys.path.insert(0, str(EXAMPLES))
    try:
        import gym_policies
    finally:
        sys.path.remove(str(EXAMPLES))
    out = gym_policies.main(["--episodes", "2", "--steps", "120"])
    assert np.mean(out["greedy"]) > np.mean(out["random"])
