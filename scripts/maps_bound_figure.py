"""The bound's screenshots of docs/maps.md: the window with the live PCRB (key B)
on, in a map world, paused at a given time.

    SDL_VIDEODRIVER=dummy python scripts/maps_bound_figure.py office 20 docs/figures/maps_bound_office.png

Runs the scenario's default filters on autopilot in the window (scripted frames, nothing
recorded), presses B at ``time`` [s] and saves the frame: the bound's dotted ellipse around
the true robot, in the magnifier's inner box when it is too small at the magnifier's zoom.
"""

from __future__ import annotations

import argparse

import pygame

from beacon_sim.app.main import SCRIPTED_FRAME_S, App
from beacon_sim.core.scenario import load_scenario
from beacon_sim.runs.live import Session


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario")
    ap.add_argument("time", type=float, help="simulated time of the frame [s]")
    ap.add_argument("out", help="PNG to write")
    ap.add_argument("--size", default="1100x640")
    args = ap.parse_args()
    w, h = (int(v) for v in args.size.split("x"))
    sc = load_scenario(args.scenario)
    s = Session(sc, list(sc.default_filters), None)
    s.toggle_autopilot()
    app = App(s, (w, h), scripted=True)
    try:
        while s.time < args.time:
            app.frame(SCRIPTED_FRAME_S)
        app.act("pause")
        app.act("bound")
        app.draw()
        pygame.image.save(app.screen, args.out)
        pos, head = app.bound.sigmas() if app.bound is not None else (float("nan"),) * 2
        print(f"{args.out}: t = {s.time:.1f} s, bound sigma {pos * 1000:.1f} mm, {head:.4f} rad")
    finally:
        app.close()


if __name__ == "__main__":
    main()
