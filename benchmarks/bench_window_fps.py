"""Frames per second the window delivers under a real X server (Xvfb), on the path it picks
itself (X11's own framebuffer, app/framebuffer.py) and on SDL's texture path
(``SDL_FRAMEBUFFER_ACCELERATION=1``), in the same run, with the median ``flip`` and the CPU
time per frame. The window's own loop (60 FPS cap), the scenario's default filters on
autopilot, 30 frames to settle, then ``--frames``.

    python benchmarks/bench_window_fps.py [--sizes 1024x768 1920x1080] [--frames 300]
        [--scenario default] [--rounds 2]

Needs ``xvfb-run`` (Debian/Ubuntu: the xvfb package). Quote the load printed beside it.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import time

PATHS = (("picked by the window", None), ("SDL's texture (=1)", "1"))


def child(size: str, frames: int, scenario: str) -> None:
    """Inside Xvfb: open the window, run it, print one line of figures."""
    os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
    import numpy as np
    import pygame

    from beacon_sim.app.main import App
    from beacon_sim.core.scenario import load_any_scenario
    from beacon_sim.core.threads import limit_blas_threads
    from beacon_sim.runs.live import Session

    limit_blas_threads()
    w, h = (int(v) for v in size.split("x"))
    team = load_any_scenario(scenario)
    sc = team.robots[0].scenario if team.solo else team
    session = Session(sc, list(team.default_filters))
    if session.has_autopilot:
        session.toggle_autopilot()
    app = App(session, (w, h))
    app.run(30)
    flips: list[float] = []
    flip = pygame.display.flip

    def timed_flip() -> None:
        t = time.perf_counter()
        flip()
        flips.append(time.perf_counter() - t)

    pygame.display.flip = timed_flip
    f0, t0, c0 = app.frames, time.perf_counter(), time.process_time()
    app.run(f0 + frames)
    wall = time.perf_counter() - t0
    print(f"FIGURES\t{(app.frames - f0) / wall:.1f}\t{1e3 * float(np.median(flips)):.2f}\t"
          f"{1e3 * (time.process_time() - c0) / frames:.2f}\t{app.framebuffer}")
    app.close()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", nargs="+", default=["1024x768", "1920x1080"])
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--scenario", default="default")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--child", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child:
        child(a.child, a.frames, a.scenario)
        return
    if shutil.which("xvfb-run") is None:
        sys.exit("bench_window_fps: needs xvfb-run (the xvfb package)")
    print(f"{a.scenario}, default filters on autopilot, {a.frames} frames, Xvfb; "
          f"load average at the start {os.getloadavg()[0]:.1f}")
    print("| size | path | FPS | flip p50 ms | CPU ms/frame | load |")
    print("|---|---|---|---|---|---|")
    for size in a.sizes:
        for _ in range(a.rounds):
            for label, value in PATHS:
                env = {k: v for k, v in os.environ.items()
                       if k not in ("SDL_FRAMEBUFFER_ACCELERATION", "SDL_VIDEODRIVER")}
                if value is not None:
                    env["SDL_FRAMEBUFFER_ACCELERATION"] = value
                out = subprocess.run(
                    ["xvfb-run", "-a", "-s", f"-screen 0 {size}x24", sys.executable, __file__,
                     "--child", size, "--frames", str(a.frames), "--scenario", a.scenario],
                    env=env, capture_output=True, text=True, check=True).stdout
                line = [ln for ln in out.splitlines() if ln.startswith("FIGURES\t")][-1]
                fps, flip, cpu, chosen = line.split("\t")[1:]
                print(f"| {size} | {label} ({chosen}) | {fps} | {flip} | {cpu} | "
                      f"{os.getloadavg()[0]:.1f} |", flush=True)


if __name__ == "__main__":
    main()
