"""Memory of the window over a long session: the resident set size while a
window's session runs one simulated hour (72,000 ticks at dt = 0.05 s) with four filters,
drawn every 10th tick, and the same for the team window on team_sparse. Prints the RSS
at seven points and the growth from the second to the last in MiB per hour; a bounded
window grows by (close to) nothing once its rings are full.

    python benchmarks/bench_window_memory.py [--minutes 60]

Linux only (reads /proc/self/statm). Headless (SDL dummy driver).
"""

from __future__ import annotations

import argparse
import os
import resource

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")

from beacon_sim.app.main import App
from beacon_sim.core.scenario import load_scenario, load_team_scenario
from beacon_sim.core.threads import limit_blas_threads
from beacon_sim.runs.live import Session

PAGE = resource.getpagesize()


def rss_mib() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * PAGE / 2**20


def soak(app, session, dt: float, minutes: int, label: str) -> None:
    ticks_per_min = round(60 / dt)
    every = max(1, minutes // 6)
    marks = []
    for minute in range(minutes + 1):
        if minute % every == 0 or minute == minutes:
            marks.append((minute, rss_mib()))
            print(f"  {label}: {minute:>3} min simulated, RSS {marks[-1][1]:7.1f} MiB", flush=True)
        if minute == minutes:
            break
        for k in range(ticks_per_min):
            session.tick()
            if k % 10 == 0:
                app.draw()
    (m0, r0), (m1, r1) = marks[1], marks[-1]
    print(f"{label}: growth {60 * (r1 - r0) / max(m1 - m0, 1):+.1f} MiB per hour "
          f"(from {m0} to {m1} min), RSS at the end {r1:.1f} MiB")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=int, default=60)
    args = ap.parse_args()
    limit_blas_threads()
    sc = load_scenario("default")
    s = Session(sc, ["ekf", "ukf", "pf", "histogram"], None, {"pf": {"n_particles": 2000}})
    s.toggle_autopilot()
    app = App(s, (1280, 800), scripted=True)
    try:
        soak(app, s, sc.dt, args.minutes, "window, default, ekf+ukf+pf+histogram")
    finally:
        app.close()
    team = load_team_scenario("team_sparse")
    ts = Session(team, list(team.default_filters))
    ts.autopilot = True
    tapp = App(ts, (1280, 800), scripted=True)
    try:
        soak(tapp, ts, team.dt, args.minutes, "team window, team_sparse, 4 team filters")
    finally:
        tapp.close()


if __name__ == "__main__":
    main()
