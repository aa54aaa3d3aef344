"""Active localisation in the Gymnasium environment: a random policy beside a greedy one.

The robot starts in the default room's blind corner (x = 10 m, y = 2 m: no beacon within
the sensor's 3 m). The reward is the shipped one, ``neg_log_det``: minus the log-determinant
of the EKF's covariance, so a policy earns more when the filter is surer of the pose.

- random: uniform actions [v, omega] from the action space;
- greedy: drive to the beacon nearest the EKF's estimate (it only uses the filter's belief,
  never the true pose) and circle it at about 1 m, keeping it in view.

Nothing is trained. Run it (``pip install 'gymnasium'``)::

    python examples/gym_policies.py                   # 3 episodes of 30 s each
    python examples/gym_policies.py --render out.png  # also save the greedy run's last frame
"""

from __future__ import annotations

import argparse
import math

import numpy as np

import beacon_sim as bs
from beacon_sim.gym import BeaconEnv

SCENARIO_CHANGES = {"robot.initial_pose": [10.0, 2.0, math.pi / 2]}


def random_policy(env: BeaconEnv, info: dict, rng: np.random.Generator) -> np.ndarray:
    return rng.uniform(env.action_space.low, env.action_space.high).astype(np.float32)


def greedy_policy(env: BeaconEnv, info: dict, rng: np.random.Generator) -> np.ndarray:
    x, y, th = info["estimate"]
    beacons = np.array([[b.x, b.y] for b in env.scenario.world.beacons])
    d = beacons - [x, y]
    k = int(np.argmin(np.hypot(d[:, 0], d[:, 1])))
    dist = float(np.hypot(*d[k]))
    heading = math.atan2(d[k, 1], d[k, 0])
    if dist < 1.2:  # close enough: orbit it, the beacon on the left
        heading -= math.pi / 2
    err = (heading - th + math.pi) % (2 * math.pi) - math.pi
    v = 0.5 if abs(err) < 1.0 else 0.1
    return np.array([v, np.clip(2.0 * err, -2.0, 2.0)], dtype=np.float32)


def episode(policy, seed: int, steps: int, render: str | None = None) -> float:
    sc = bs.load_scenario("default", SCENARIO_CHANGES)
    env = BeaconEnv(sc, ["ekf"], max_steps=steps, render_mode="rgb_array" if render else None)
    rng = np.random.default_rng(seed)
    _, info = env.reset(seed=seed)
    total, done = 0.0, False
    while not done:
        _, reward, terminated, truncated, info = env.step(policy(env, info, rng))
        total += reward
        done = terminated or truncated
    if render:
        from PIL import Image

        Image.fromarray(env.render()).save(render)
    env.close()
    return total / steps


def main(argv: list[str] | None = None) -> dict[str, list[float]]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=3)
    ap.add_argument("--steps", type=int, default=300, help="steps per episode (0.1 s each)")
    ap.add_argument("--render", metavar="PNG", help="save the greedy policy's last frame")
    args = ap.parse_args(argv)
    out: dict[str, list[float]] = {}
    for name, policy in (("random", random_policy), ("greedy", greedy_policy)):
        out[name] = [episode(policy, seed, args.steps, args.render if name == "greedy" and seed == 0
                             else None) for seed in range(args.episodes)]
    print(f"mean reward per step (-log det P of the EKF; higher = surer), {args.episodes} episodes "
          f"of {args.steps} steps:")
    for name, values in out.items():
        print(f"  {name:7s} {np.mean(values):7.2f}   per episode: {', '.join(f'{v:.2f}' for v in values)}")
    return out


if __name__ == "__main__":
    main()
