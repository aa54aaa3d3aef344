"""The window's screenshots in docs/window.md, at a projector's 1024x768 and at
1920x1080, made with the window's own drawing (SDL's dummy driver, scripted frames):

- ``three``: assignment_kf 52.9 s in, three beacons in view, the KF's 4 cm ellipse in the
  magnifier;
- ``blind``: assignment_kf 18.2 s in, 8 s without a beacon, the strip chart on;
- ``help``: the help overlay (H) over assignment_kf;
- ``particles``: global_kidnap at t = 0, the particles and the grid spread over the room;
- ``team``: team_sparse 20 s in, every robot on its driver.

With ``--classroom`` it also makes docs/window.md's four classroom pictures (1600x1000, the
strip chart on, more filters than the scenarios' defaults: see ``CLASSROOM``) and the
README's docs/screenshot.png (1280x800).

Each PNG is reduced to a 256-colour palette (Pillow) to stay small. Run from the checkout:

    SDL_VIDEODRIVER=dummy python scripts/window_figures.py [--out docs/figures] [--classroom]
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

SIZES = ((1024, 768), (1920, 1080))
#: name -> (scenario, simulated time [s], strip chart, help overlay)
SHOTS = {
    "three": ("assignment_kf", 52.9, False, False),
    "blind": ("assignment_kf", 18.2, True, False),
    "help": ("assignment_kf", 5.0, False, True),
    "particles": ("global_kidnap", 0.0, False, False),
    "team": ("team_sparse", 20.0, False, False),
}


#: docs/<name>.png -> (scenario, filters, simulated time [s], size, strip chart)
CLASSROOM = {
    "classroom_assignment_kf_blind": ("assignment_kf", ["kf", "ekf", "ukf", "dead_reckoning"],
                                      18.2, (1600, 1000), True),
    "classroom_assignment_kf_three": ("assignment_kf", ["kf", "ekf", "ukf", "dead_reckoning"],
                                      52.9, (1600, 1000), True),
    "classroom_default_blind": ("default", ["ekf", "ukf", "dead_reckoning"], 24.0, (1600, 1000), True),
    "classroom_default_three": ("default", ["ekf", "ukf", "dead_reckoning"], 34.3, (1600, 1000), True),
    # as `beacon-sim play default --filter ekf --filter pf --filter histogram --filter
    # dead_reckoning --autopilot --frames 1100` (18.3 s)
    "screenshot": ("default", ["ekf", "pf", "histogram", "dead_reckoning"], 18.3, (1280, 800), False),
}


def make_app(scenario: str, size: tuple[int, int], filters: list[str] | None = None,
             autopilot: bool = True):
    """The window on ``filters`` (default: ``scenario``'s default filters), its driver at
    the wheel (``autopilot`` False: the robot stands still until driven)."""
    from beacon_sim.app.main import App
    from beacon_sim.core.scenario import is_team_scenario, load_scenario, load_team_scenario
    from beacon_sim.runs.live import Session

    if is_team_scenario(scenario):
        from beacon_sim.app.main import App
        from beacon_sim.runs.live import Session

        team = load_team_scenario(scenario)
        ts = Session(team, list(team.default_filters))
        ts.toggle_autopilot()
        return App(ts, size, scripted=True)
    sc = load_scenario(scenario)
    s = Session(sc, list(filters or sc.default_filters))
    if autopilot:
        s.toggle_autopilot()
    return App(s, size, scripted=True)


def tick_to(app, t: float) -> None:
    """Run the window's session to the simulated time ``t`` [s] without drawing (the
    window's banners and strip chart follow each tick)."""
    s = app.session
    while s.time < t - 1e-9:
        app.after_tick(s.tick())


def save_png(app, path: Path) -> Path:
    """The window's present picture into ``path`` as a 256-colour palette PNG."""
    from PIL import Image

    tmp = path.with_suffix(".tmp.png")
    app.save_screenshot(tmp)
    img = Image.open(tmp).convert("RGB").quantize(256, method=Image.Quantize.MEDIANCUT)
    img.save(path, optimize=True)
    tmp.unlink()
    return path


def shoot(name: str, size: tuple[int, int], out: Path, filters: list[str] | None = None,
          path: Path | None = None) -> Path:
    """One screenshot: tick to the time, draw one frame, save as a palette PNG."""
    scenario, t, chart, help_on = SHOTS[name]
    app = make_app(scenario, size, filters)
    try:
        if chart:
            app.act("chart")
        tick_to(app, t)
        app.help = help_on
        app.run(app.frames + 1 if t > 0 else 0)  # t = 0: the first picture, before any tick
        return save_png(app, path or out / f"window_{name}_{size[0]}x{size[1]}.png")
    finally:
        app.close()


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="docs/figures", help="folder for the PNGs")
    p.add_argument("--only", nargs="*", choices=sorted(SHOTS), help="these shots only")
    p.add_argument("--classroom", action="store_true", help="also docs/classroom_*.png and "
                   "docs/screenshot.png")
    args = p.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for name in args.only or SHOTS:
        for size in SIZES:
            path = shoot(name, size, out)
            print(f"{path}: {path.stat().st_size / 1024:.0f} KB")
    if args.classroom:
        for name, (scenario, filters, t, size, chart) in CLASSROOM.items():
            SHOTS[name] = (scenario, t, chart, False)
            path = shoot(name, size, out, filters, Path("docs") / f"{name}.png")
            print(f"{path}: {path.stat().st_size / 1024:.0f} KB")


if __name__ == "__main__":
    main()
