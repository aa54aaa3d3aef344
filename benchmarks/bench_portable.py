"""The cost of the portable maths: the simulation and a headless run, on this
checkout against another commit (default: the one before the portable maths), interleaved.

    python benchmarks/bench_portable.py [--before REF] [--rounds N]

Each round runs, in a fresh process per tree and alternating the trees, (a) the simulation
alone: 3000 ticks of each of default (bearings and range-bearings), office (a laser scan in a
world with walls) and krejsa_bearing_only; (b) a headless run of default with its filters, as
``beacon-sim run default --duration 300`` does. The CPU time of each (``time.process_time``)
is taken; the median over the rounds and the ratio after / before are printed.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from figures import figure

ROOT = Path(__file__).resolve().parents[1]
BEFORE = "d0fca64"   # main just before the portable maths

WORK = r'''
import json, sys, time
from beacon_sim.core.threads import limit_blas_threads
limit_blas_threads()
from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.simulation import Simulation
out = {}
for name in ("default", "office", "krejsa_bearing_only"):
    sim = Simulation(load_scenario(name))
    t = time.process_time()
    for _ in range(3000):
        sim.step()
    out["sim " + name] = (time.process_time() - t) / 3000 * 1e6
from beacon_sim.runs.headless import run_headless
sc = load_scenario("default")
t = time.process_time()
run_headless(sc, duration=300.0)
out["headless default 300 s"] = time.process_time() - t
print(json.dumps(out))
'''


def measure(tree: Path) -> dict[str, float]:
    done = subprocess.run([sys.executable, "-c", WORK], cwd=tree, capture_output=True, text=True,
                          env={"PYTHONPATH": str(tree), "PATH": "/usr/bin:/bin"}, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", default=BEFORE, help="the commit to compare with")
    ap.add_argument("--rounds", type=int, default=5)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        old = Path(tmp) / "before"
        old.mkdir()
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", args.before, "beacon_sim",
                                  "scenarios", "assets"], capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", str(old)], input=archive, check=True)
        runs: dict[str, list[dict[str, float]]] = {"before": [], "after": []}
        for _ in range(args.rounds):
            runs["before"].append(measure(old))
            runs["after"].append(measure(ROOT))
    print(f"{'what':28s} {'before':>10s} {'after':>10s} {'ratio':>7s}   (CPU, median of {args.rounds})")
    for key in runs["after"][0]:
        b = statistics.median(r[key] for r in runs["before"])
        a = statistics.median(r[key] for r in runs["after"])
        unit = "s" if key.startswith("headless") else "us/tick"
        print(f"{key:28s} {b:10.3f} {a:10.3f} {a / b:7.3f}   {unit}")
        figure(f"portable maths: {key}", a, unit, peer=f"{args.before} (numpy's kernels)", peer_value=b)


if __name__ == "__main__":
    main()
