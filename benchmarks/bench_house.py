"""The single-robot and team paths against an earlier commit (the target: no slower).

Each round runs, in a fresh process per tree, alternating this checkout and ``--base``: a
headless run of ``default`` with four filters (60 s simulated), a live Session ticking 1,200
times with ekf + dead reckoning (no window), and a headless team run of ``team_sparse`` with
four team filters (60 s). Figures are CPU seconds (``time.process_time``), medians of the
rounds, and the ratio this / base (target <= 1.0, within the noise of a shared machine).

    python benchmarks/bench_house.py --rounds 7 --base a5d21dd
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_frames import extract
from figures import figure

ROOT = Path(__file__).resolve().parents[1]

#: Runs in the tree on PYTHONPATH; prints one JSON line of CPU seconds per path. It uses only
#: names both the old and the new tree have (the team run through whichever entry point exists).
WORKER = r'''
import json, time
from beacon_sim.core.threads import limit_blas_threads
limit_blas_threads()
from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.scenario import load_team_scenario
from beacon_sim.runs.headless import run_headless
from beacon_sim.runs.live import Session
try:
    from beacon_sim.runs.team import run_team_headless as run_team
except ImportError:  # a single robot is a team of one: one run_headless
    run_team = run_headless
sc = load_scenario("default")
out = {}
c = time.process_time()
run_headless(sc, ["ekf", "ukf", "pf", "dead_reckoning"], seed=1, duration=60)
out["headless default, 4 filters, 60 s"] = time.process_time() - c
s = Session(sc, ["ekf", "dead_reckoning"], seed=1)
s.toggle_autopilot()
c = time.process_time()
for _ in range(1200):
    s.tick()
out["live Session, 1200 ticks"] = time.process_time() - c
team = load_team_scenario("team_sparse")
c = time.process_time()
run_team(team, ["independent", "centralised", "ci", "independent:ekf"], seed=1, duration=60)
out["team run, 4 filters, 60 s"] = time.process_time() - c
print(json.dumps(out))
'''


def one(tree: Path) -> dict[str, float]:
    env = {**os.environ, "PYTHONPATH": str(tree)}
    p = subprocess.run([sys.executable, "-c", WORKER], env=env, cwd=tree, capture_output=True,
                       text=True, check=True)
    return json.loads(p.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--base", default="a5d21dd", help="the commit to compare with")
    args = ap.parse_args()
    base = extract(args.base)
    trees = {"this": ROOT, "base": base}
    got: dict[str, list[dict[str, float]]] = {k: [] for k in trees}
    print(f"load average {os.getloadavg()[0]:.1f} at start")
    for _ in range(args.rounds):
        for name, tree in trees.items():
            got[name].append(one(tree))
    for what in got["this"][0]:
        a = statistics.median(r[what] for r in got["this"])
        b = statistics.median(r[what] for r in got["base"])
        print(f"{what:36s} this {a:7.3f} s CPU  base {b:7.3f} s CPU  this/base {a / b:5.2f}")
        figure(what, a, "s", peer=f"base {args.base}", peer_value=b, target=1.0,
               target_of="ratio", cpu=a)
    print(f"load average {os.getloadavg()[0]:.1f} at end; medians of {args.rounds} rounds")


if __name__ == "__main__":
    main()
