"""Cost per step of the team filters for 2, 5 and 10 robots (docs/multi-robot.md).

A 20 m x 20 m room with 12 beacons; N robots on random-goal tours, each with a 4 m
range-bearing beacon sensor and a robot range-bearing sensor of unlimited range at 10 Hz
(every robot sees every other one: the most rows a joint update can get). Prints the mean
wall time per tick [us] of each team filter (predict + update + estimates) and the rows.

    python benchmarks/bench_team.py [--duration 30]
"""

from __future__ import annotations

import argparse
import os

import numpy as np

from beacon_sim.core.scenario import parse_team_scenario
from beacon_sim.runs.headless import run_headless


def team_doc(n: int) -> dict:
    rng = np.random.default_rng(0)
    beacons = [{"id": k + 1, "x": float(x), "y": float(y)}
               for k, (x, y) in enumerate(rng.uniform(1, 19, (12, 2)))]
    robots = []
    for i in range(n):
        x, y = rng.uniform(2, 18, 2)
        robots.append({
            "name": f"r{i + 1}", "id": i + 1, "initial_pose": [float(x), float(y), 0.0],
            "motion_noise": {"v_std": 0.02, "v_frac": 0.2, "omega_std": 0.05, "omega_frac": 0.1},
            "driver": {"kind": "random_goal", "speed": 0.3},
            "sensors": [
                {"name": "beacons", "kind": "range_bearing", "period": 0.1, "max_range": 4.0,
                 "range_std": 0.05, "bearing_std": 0.03},
                {"name": "teammates", "kind": "robot_range_bearing", "period": 0.1,
                 "range_std": 0.05, "bearing_std": 0.03},
            ]})
    return {"name": f"bench_team_{n}", "dt": 0.05, "duration": 60.0, "seed": 1,
            "world": {"bounds": [0.0, 0.0, 20.0, 20.0], "beacons": beacons}, "robots": robots}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--duration", type=float, default=30.0)
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.1f} (1 min)")
    print(f"{'robots':>6} {'filter':>14} {'us/step':>9} {'robot rows/tick':>16}")
    for n in (2, 5, 10):
        team = parse_team_scenario(team_doc(n), f"bench_team_{n}")
        r = run_headless(team, ["independent", "centralised", "decentralised", "ci"],
                         duration=args.duration)
        rows = sum(len(m) for s in r.team_steps for ms in s.robot_readings for m in ms) / len(r.team_steps)
        for name, tr in r.tracks.items():
            print(f"{n:>6} {name:>14} {tr.us_per_step:>9.0f} {rows:>16.1f}")


if __name__ == "__main__":
    main()
