"""CPU time per frame of every shipped view: a row per shipped scenario (its default filters,
on autopilot) and per heavier command the docs show, at 1280x800 and 1920x1080, with the
SDL dummy driver and the frames as ``App.run`` runs them (smooth drawing, heap settling).

Prints p50 and p99 of the process's CPU time per frame (less affected by other jobs than
wall time) against the targets, p99 <= 8 ms at 1280x800 and <= 10 ms at 1920x1080 on an
idle 2-core machine, "met" or "NOT met", the load average, and the filters the window's
time limit switched off (none expected, whatever the load); a last row gives the load the
whole run saw and how many rows met their target. With one BLAS thread, as the window
has. ``--load N`` runs N busy-spinning processes beside it (the row "at load >= 8").

The frames here run the filters in each tick (as ``--frames N`` does); the window itself runs
them on a worker thread: ``bench_frame_threads.py`` measures its main thread's CPU per frame
against this way, in the same run.

    python benchmarks/bench_frame_views.py [--frames 300] [--sizes 1280x800 1920x1080]
        [--only default office ...] [--load 8]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")

import numpy as np

from beacon_sim.core.threads import limit_blas_threads

limit_blas_threads()  # one BLAS thread, as the window has (``beacon-sim`` sets it at start)

from beacon_sim.app.main import SCRIPTED_FRAME_S, App  # noqa: E402
from beacon_sim.core.resources import scenario_dir  # noqa: E402
from beacon_sim.core.scenario import load_any_scenario  # noqa: E402
from beacon_sim.runs.live import Session  # noqa: E402

#: The heavier commands the docs show, beyond each scenario's defaults: (label, scenario,
#: filters or None for the defaults, parameters).
DOC_COMMANDS: list[tuple[str, str, list[str] | None, dict]] = [
    ("README's picture", "default", ["ekf", "pf", "histogram", "dead_reckoning"], {}),
    ("heavy beacon view", "default", ["ekf", "ukf", "pf", "histogram"], {"pf": {"n_particles": 10000}}),
    ("maps.md office mcl 10k", "office", None, {"mcl": {"max_particles": 10000}}),
    ("particle-and-grid.md", "sparse_kidnap", ["pf", "histogram"], {}),
    ("multi-robot.md", "team_sparse", ["centralised", "ci"], {}),
]
TARGET_MS = {(1280, 800): 8.0, (1920, 1080): 10.0}


def shipped() -> list[str]:
    """Every shipped scenario's name (single-robot and team)."""
    root = scenario_dir()
    names = sorted(p.stem for p in root.glob("*.toml"))
    return names + sorted(p.stem for p in (root / "team").glob("*.toml"))


def bench(scenario: str, specs: list[str] | None, params: dict, size: tuple[int, int],
          frames: int, warmup: int = 30) -> dict:
    """CPU time per frame [ms] of one view: p50, p99; the filters switched off."""
    team = load_any_scenario(scenario)
    sc = team.robots[0].scenario if team.solo else team
    session = Session(sc, list(specs or team.default_filters), None, params)
    if session.has_autopilot:
        session.toggle_autopilot()
    app = App(session, size, scripted=True)
    app.smooth = app.settle_heap = True
    try:
        for _ in range(warmup):
            app.frame(SCRIPTED_FRAME_S)
        cpu = np.empty(frames)
        for i in range(frames):
            c0 = time.process_time()
            app.frame(SCRIPTED_FRAME_S)
            cpu[i] = time.process_time() - c0
        off = {n: session.status[n].failed for n in session.names if session.status[n].failed}
        names = list(session.names)
    finally:
        app.close()
    return {"p50": 1e3 * float(np.median(cpu)), "p99": 1e3 * float(np.percentile(cpu, 99)),
            "off": off, "filters": names}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--sizes", nargs="+", default=["1280x800", "1920x1080"])
    ap.add_argument("--only", nargs="+", help="only these scenarios (their rows and commands)")
    ap.add_argument("--load", type=int, default=0, help="busy-spinning processes beside the run")
    a = ap.parse_args()
    rows: list[tuple[str, str, list[str] | None, dict]] = [(s, s, None, {}) for s in shipped()]
    rows += DOC_COMMANDS
    if a.only:
        rows = [r for r in rows if r[1] in a.only]
    spinners = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(a.load)]
    try:
        print(f"load average at the start {os.getloadavg()[0]:.1f}; {a.load} busy spinners; "
              f"{a.frames} frames per row; CPU time per frame of this process")
        print("| view | filters | size | p50 ms | p99 ms | target | verdict | switched off | load |")
        print("|---|---|---|---|---|---|---|---|---|")
        loads = [os.getloadavg()[0]]
        met = total = 0
        for label, scenario, specs, params in rows:
            for text in a.sizes:
                w, h = (int(v) for v in text.split("x"))
                r = bench(scenario, specs, params, (w, h), a.frames)
                target = TARGET_MS.get((w, h), 10.0)
                verdict = "met" if r["p99"] <= target else "NOT met"
                off = ", ".join(f"{k} ({v})" for k, v in r["off"].items()) or "none"
                loads.append(os.getloadavg()[0])
                met, total = met + (verdict == "met"), total + 1
                print(f"| {label} | {' + '.join(r['filters'])} | {w}x{h} | {r['p50']:.1f} | "
                      f"{r['p99']:.1f} | {target:g} | {verdict} | {off} | "
                      f"{loads[-1]:.1f} |", flush=True)
        # the load the whole run saw: read every figure above against it (the targets are
        # for an idle 2-core machine)
        print(f"| load (1-min average over the run) | {a.load} busy spinners | | | | | "
              f"{met} of {total} met | | {min(loads):.1f}-{max(loads):.1f} |", flush=True)
    finally:
        for p in spinners:
            p.kill()
            p.wait()


if __name__ == "__main__":
    main()
