"""The Gymnasium env where users meet it: ``gym.make`` in a fresh process, the
spec's episode length, bad actions refused in one line, and pickling (vector envs, saving)."""

from __future__ import annotations

import pickle
import subprocess
import sys
from pathlib import Path

import gymnasium
import numpy as np
import pytest

from beacon_sim.errors import BeaconSimError
from beacon_sim.gym import DEFAULT_MAX_STEPS, ENV_ID, MAKE_ID, BeaconEnv, NegLogDet

ROOT = Path(__file__).resolve().parents[2]

FRESH = f"""
import gymnasium as gym, numpy as np
try:
    gym.make({ENV_ID!r})
except gym.error.NamespaceNotFound:
    print("plain id: NamespaceNotFound")
env = gym.make({MAKE_ID!r}, scenario="default")
print("max_episode_steps", env.spec.max_episode_steps)
obs, info = env.reset(seed=3)
total = 0.0
for _ in range(5):
    obs, r, term, trunc, info = env.step(np.array([0.5, 0.1], dtype=np.float32))
    total += r
print("obs", obs.shape, "finite", bool(np.isfinite(total)), "time", round(info["time"], 3))
"""


def test_gym_make_with_the_module_prefix_works_in_a_fresh_process(tmp_path):
    env = {"PYTHONPATH": str(ROOT), "SDL_VIDEODRIVER": "dummy", "SDL_AUDIODRIVER": "dummy",
           "PATH": "/usr/bin:/bin"}
    out = subprocess.run([sys.executable, "-c", FRESH], capture_output=True, text=True, cwd=tmp_path,
                         env=env, timeout=300)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert "plain id: NamespaceNotFound" in lines  # why docs/gym.md gives the prefixed form
    assert f"max_episode_steps {DEFAULT_MAX_STEPS}" in lines
    assert "obs (28,) finite True time 0.5" in lines  # 5 steps of 2 ticks of 50 ms


def test_the_specs_episode_length_is_the_default_envs():
    assert BeaconEnv().max_steps == DEFAULT_MAX_STEPS
    spec = gymnasium.spec(ENV_ID)
    assert spec.max_episode_steps == DEFAULT_MAX_STEPS
    env = gymnasium.make(ENV_ID, max_episode_steps=3)
    env.reset(seed=0)
    truncated = [env.step(np.zeros(2, dtype=np.float32))[3] for _ in range(3)]
    assert truncated == [False, False, True]


@pytest.mark.parametrize("action, message", [
    ([np.nan, 0.0], r"action \[nan, 0.0\]: expected finite numbers"),
    ([0.5, np.inf], "expected finite numbers"),
    ([1.0], r"action of shape \(1,\): expected shape \(2,\)"),
    ([1.0, 2.0, 3.0], r"shape \(3,\)"),
    ([[0.1, 0.2]], r"shape \(1, 2\)"),
    ("fast", "expected two numbers"),
])
def test_bad_actions_are_refused_in_one_line(action, message):
    env = BeaconEnv()
    env.reset(seed=0)
    with pytest.raises(BeaconSimError, match=message) as got:
        env.step(action)
    assert isinstance(got.value, ValueError) and "\n" not in str(got.value)
    assert env.steps_taken == 0  # nothing ran
    env.step([0.3, 0.0])  # the env still works


def test_the_env_pickles_mid_episode_and_goes_on_bit_for_bit():
    env = BeaconEnv("sparse_kidnap", filters=("ekf", "pf"), params={"pf": {"n_particles": 200}})
    assert pickle.loads(pickle.dumps(env)).max_steps == env.max_steps  # before reset too
    env.reset(seed=5)
    rng = np.random.default_rng(1)
    for _ in range(20):
        env.step(rng.uniform(-1, 1, 2))
    twin = pickle.loads(pickle.dumps(env))
    assert isinstance(twin.reward_fn, NegLogDet) and twin.steps_taken == 20
    for _ in range(10):
        a = rng.uniform(-1, 1, 2)
        o1, r1, t1, u1, i1 = env.step(a)
        o2, r2, t2, u2, i2 = twin.step(a)
        np.testing.assert_array_equal(o1, o2)
        assert r1 == r2 and (t1, u1) == (t2, u2)
        np.testing.assert_array_equal(i1["true_pose"], i2["true_pose"])
        np.testing.assert_array_equal(i1["cov"], i2["cov"])
    # and reset() after unpickling draws the same episodes as the original would
    np.testing.assert_array_equal(env.reset()[0], twin.reset()[0])
