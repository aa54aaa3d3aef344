"""Frame time of the window, headless (SDL dummy driver), at 1280x800.

Runs the default scenario on autopilot at x1 with ekf + ukf + pf + histogram all drawn
(the ones that are installed), with the strip chart (C) off and then on in the same run,
and prints the median and 99th percentile of the frame time and the load average: events,
the simulation ticks due (dt = 0.05 s: one tick every third frame), every filter's update,
drawing and flip. Targets on the 2-core machine: p99 <= 8 ms at load < 2 and <= 16.7 ms (60 FPS) at
load 4 with 10,000 particles; median <= 33 ms with 100,000. The frames run as ``App.run``
runs them (smooth drawing and heap settling); ``bench_frames.py`` compares views
and window sizes against an older commit.

    python benchmarks/bench_frame.py [--frames 400] [--particles 10000 100000]
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")

import numpy as np
from figures import figure

from beacon_sim.app.main import SCRIPTED_FRAME_S, App
from beacon_sim.core.scenario import load_scenario
from beacon_sim.hosting.loading import available_filters
from beacon_sim.runs.live import Session

WANTED = ("ekf", "ukf", "pf", "histogram")


def bench(n_particles: int, frames: int, warmup: int = 30, chart: bool = True) -> dict:
    sc = load_scenario("default")
    specs = [f for f in WANTED if f in available_filters()]
    params = {"pf": {"n_particles": n_particles}}
    session = Session(sc, specs, None, params)
    session.toggle_autopilot()
    app = App(session, (1280, 800), scripted=True)
    if chart:
        app.act("chart")  # the strip chart on: the classroom view's heaviest frame
    app.smooth = app.settle_heap = True  # what App.run switches on
    try:
        for _ in range(warmup):
            app.frame(SCRIPTED_FRAME_S)
        times = np.empty(frames)
        cpu = np.empty(frames)  # CPU time of this process: less affected by other jobs
        for i in range(frames):
            c0, t0 = time.process_time(), time.perf_counter()
            app.frame(SCRIPTED_FRAME_S)
            times[i] = time.perf_counter() - t0
            cpu[i] = time.process_time() - c0
        app.smooth = False  # every draw() draws everything again
        draw = []
        for _ in range(60):  # drawing alone (no tick), the part the window adds
            app.now += SCRIPTED_FRAME_S
            app.chart.version += 1  # as if a tick had come: the chart is due when it may be
            t0 = time.perf_counter()
            app.draw()
            draw.append(time.perf_counter() - t0)
        per_filter = {n: t.us_per_step / 1e3 for n, t in session.runner.tracks.items()}
    finally:
        app.close()
    return {"filter_ms_per_tick": per_filter, "filters": specs, "particles": n_particles,
            "median_ms": 1e3 * float(np.median(times)),
            "p99_ms": 1e3 * float(np.percentile(times, 99)), "max_ms": 1e3 * float(times.max()),
            "cpu_median_ms": 1e3 * float(np.median(cpu)), "cpu_p99_ms": 1e3 * float(np.percentile(cpu, 99)),
            "draw_median_ms": 1e3 * float(np.median(draw))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=400)
    ap.add_argument("--particles", type=int, nargs="+", default=[10_000, 100_000])
    args = ap.parse_args()
    for n in args.particles:
        for chart in (False, True):
            load = os.getloadavg()[0]
            r = bench(n, args.frames, chart=chart)
            on = "chart on " if chart else "chart off"
            print(f"{on}: {' + '.join(r['filters'])}, pf {n:,} particles, {args.frames} frames at "
                  f"1280x800: median {r['median_ms']:.2f} ms, p99 {r['p99_ms']:.2f} ms, max "
                  f"{r['max_ms']:.2f} ms (drawing alone: median {r['draw_median_ms']:.2f} ms); CPU "
                  f"time median {r['cpu_median_ms']:.2f} ms, p99 {r['cpu_p99_ms']:.2f} ms; load "
                  f"average {load:.1f}")
            print("  filter update per tick: " + ", ".join(
                f"{k} {v:.2f} ms" for k, v in r["filter_ms_per_tick"].items()))
            what = f"frame, {' + '.join(r['filters'])}, pf {n:,}, {on.strip()}"
            if n <= 10_000:   # targets: p99 <= 8 ms at load < 2, <= 16.7 ms (60 FPS) at load 4
                figure(what + ", p99", r["p99_ms"], "ms", target=8.0 if load < 2 else 16.7,
                       cpu=r["cpu_p99_ms"])
            else:
                figure(what + ", median", r["median_ms"], "ms", target=33.0, cpu=r["cpu_median_ms"])


if __name__ == "__main__":
    main()
