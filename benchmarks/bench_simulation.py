"""Steps per second of the bare simulation (truth + sensors + events, no filter).

Prints, per shipped scenario, steps/s and the real-time factor (simulated seconds per wall
second), beside a peer measured in the same run: the motion model alone (one `move` call
per step), the floor any step costs. Usage: python benchmarks/bench_simulation.py
"""

from __future__ import annotations

import time

import numpy as np
from figures import figure

from beacon_sim.core.motion import move
from beacon_sim.core.resources import shipped_scenarios
from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.simulation import Simulation


def best_rate(fn, n, repeats=3):
    best = 0.0
    for _ in range(repeats):
        t = time.perf_counter()
        fn(n)
        best = max(best, n / (time.perf_counter() - t))
    return best


def main() -> None:
    n = 5000

    def bare_move(k):
        p = np.zeros(3)
        for _ in range(k):
            p = move(p, 0.3, 0.1, 0.1)

    floor = best_rate(bare_move, n)
    print(f"{'scenario':<22}{'steps/s':>10}{'x real time':>13}{'move() only / sim':>19}")
    for name in shipped_scenarios():
        sc = load_scenario(name)

        def run(k, sc=sc):
            sim = Simulation(sc, 0)
            for _ in range(k):
                sim.step()

        rate = best_rate(run, n)
        print(f"{name:<22}{rate:>10.0f}{rate * sc.dt:>13.0f}{floor / rate:>19.1f}")
        figure(f"simulation step, {name}", 1e6 / rate, "us", peer="move() alone",
               peer_value=1e6 / floor)
    print(f"{'(peer) move() only':<22}{floor:>10.0f}")


if __name__ == "__main__":
    main()
