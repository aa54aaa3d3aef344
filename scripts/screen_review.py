"""Screens to review by eye, at 1024x768 and 1920x1080: one PNG per thing the window must
show right in a classroom (nothing hides the world or the robot, no alarm a class cannot
explain, a switched-off filter said on the world), each named for what it shows, made with
the window's own drawing (SDL's dummy driver, scripted frames, keys posted through pygame as
a user presses them). Open every picture and check it against what its name says.

- ``filter_off_by_fault_said_on_the_world`` / ``filter_off_back_after_R``: a filter that
  raises is switched off, said in a box on the world; R brings it back;
- ``nees_no_badge_dead_reckoning_at_start_{default,assignment_kf}``: no NEES badge at t = 1 s
  on dead reckoning started on the truth; the panel's last lines say what the badge means;
  ``nees_no_badge_healthy_ekf_60s_default``: a consistent EKF after a minute;
- ``pf_standstill_60s_{default,two_rooms}``: the particle filter after 10 s of driving, X,
  then 60 s standing still;
- ``magnifier_{global_kidnap_25s,assignment_kf_blind,assignment_kf_three,slam_loop_closure}``:
  the magnifier (where it opens) placed where it hides no beacon and not the robot;
- ``step_view_box_robot_bottom_left``, ``step_view_box_assignment_kf``: the step view's box
  (paused, one tick with ., B) not over the robot; ``bumper_banner_robot_at_top``: the bumper banner not
  over the robot at the top wall;
- ``replay_kidnap_banner`` / ``replay_after_seek_no_banner``: a replay's kidnap banner, then
  gone after a seek (Left);
- ``slam_bearing_only_two_colours``: its two filters in distinct colours;
- ``lost_belief_dead_reckoning``: a belief wider than the world, drawn without lines across it;
- ``corridor_misses_apart_from_wall_hits``: the corridor's range readings that hit nothing
  drawn apart from wall hits;
- ``two_rooms_sensor_disc_clipped``: the sensor disc stopped by the walls;
- ``team_panel_footer``: team_sparse's panel with its FPS line and help hint;
- ``mrclam_window_size``: ``beacon-sim mrclam DIR --robot 1 --size WxH``, 40 s in (when
  ``BEACON_SIM_MRCLAM`` names the data set's folder): title and missed list inside;
- ``kf_inside_bound_assignment_kf_blind``: B on in the blind stretch, and what the screen
  says of the KF inside the bound;
- ``f12_saved_file_no_banner`` (the file F12 wrote) / ``f12_window_saved_banner`` (the
  window after it, with its banner).

Run from the checkout (never writes into it; the folder is printed at the end):

    SDL_VIDEODRIVER=dummy python scripts/screen_review.py [--out DIR] [--only NAME ...]
"""

from __future__ import annotations

import argparse
import math
import os
import shutil
import sys
import tempfile
import textwrap
from collections.abc import Callable
from pathlib import Path

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

sys.path.insert(0, str(Path(__file__).resolve().parent))
from window_figures import SIZES, make_app, save_png, tick_to

FAULTY = textwrap.dedent('''
    from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter

    class Faulty(ExtendedKalmanFilter):
        """An EKF whose 60th update raises (a student's filter with a bug)."""
        def reset(self, initial):
            super().reset(initial)
            self.updates = 0
        def update(self, *args, **kwargs):
            self.updates += 1
            if self.updates == 60:
                raise ValueError("index 3 is out of bounds for axis 0 with size 3")
            return super().update(*args, **kwargs)
''')


def press(app, key_name: str, frames: int = 1) -> None:
    """Post a key press (down and up) through pygame, as a user's, and run ``frames``
    frames (the first handles it)."""
    import pygame

    code = getattr(pygame, key_name)
    for kind in (pygame.KEYDOWN, pygame.KEYUP):
        pygame.event.post(pygame.event.Event(kind, key=code, mod=0, unicode="", scancode=0))
    app.run(app.frames + frames)


def name_of(item: str, size: tuple[int, int]) -> str:
    return f"{item}_{size[0]}x{size[1]}.png"


class Review:
    """The shots, each a method ``shot_<group>(size)`` that saves one or more PNGs."""

    def __init__(self, out: Path):
        self.out = out
        self.saved: list[Path] = []

    def save(self, app, item: str, size) -> None:
        self.saved.append(save_png(app, self.out / name_of(item, size)))
        print(self.saved[-1], flush=True)

    # --- a switched-off filter --------------------------------------------------------------
    def shot_filter_off(self, size) -> None:
        faulty = self.out / "faulty_filter.py"
        faulty.write_text(FAULTY)
        app = make_app("default", size, ["ekf", f"{faulty}:Faulty", "dead_reckoning"])
        try:
            tick_to(app, 8.0)
            app.run(app.frames + 2)
            assert app.session.status["Faulty"].failed, "the faulty filter should be off"
            self.save(app, "filter_off_by_fault_said_on_the_world", size)
            press(app, "K_r", 30)  # R: back on (for 59 more updates)
            assert not app.session.status["Faulty"].failed
            self.save(app, "filter_off_back_after_R", size)
        finally:
            app.close()

    # --- the NEES badge ---------------------------------------------------------------------
    def shot_nees(self, size) -> None:
        for scenario in ("default", "assignment_kf"):
            app = make_app(scenario, size)
            try:
                tick_to(app, 1.0)
                app.run(app.frames + 1)
                self.save(app, f"nees_no_badge_dead_reckoning_at_start_{scenario}", size)
                if scenario == "default":
                    tick_to(app, 60.0)
                    app.run(app.frames + 1)
                    self.save(app, "nees_no_badge_healthy_ekf_60s_default", size)
            finally:
                app.close()

    # --- the particle filter at rest --------------------------------------------------------
    def shot_standstill(self, size) -> None:
        for scenario, filters in (("default", ["ekf", "pf"]), ("two_rooms", None)):
            app = make_app(scenario, size, filters)
            try:
                tick_to(app, 10.0)
                press(app, "K_m")  # the autopilot off
                press(app, "K_x")  # X: stop
                tick_to(app, app.session.time + 60.0)
                app.run(app.frames + 1)
                self.save(app, f"pf_standstill_60s_{scenario}", size)
            finally:
                app.close()

    # --- the magnifier ----------------------------------------------------------------------
    def shot_magnifier(self, size) -> None:
        for item, scenario, t, filters in (
                ("magnifier_global_kidnap_25s", "global_kidnap", 25.0, None),
                ("magnifier_assignment_kf_blind", "assignment_kf", 18.2, None),
                ("magnifier_assignment_kf_three", "assignment_kf", 52.9, ["kf", "ekf", "dead_reckoning"]),
                ("magnifier_slam_loop_closure", "slam_loop", 76.0, None)):
            app = make_app(scenario, size, filters)
            try:
                tick_to(app, t)
                app.run(app.frames + 1)
                self.save(app, item, size)
            finally:
                app.close()

    # --- the step view's box and the banner -------------------------------------------------
    def shot_step_and_banner(self, size) -> None:
        app = make_app("default", size, ["ekf", "dead_reckoning"], autopilot=False)
        try:
            x0, y0, x1, y1 = app.session.scenario.world.bounds
            app.session.command({"kind": "kidnap", "pose": [x0 + 0.6, y0 + 0.6, 0.0]})
            app.run(60)
            press(app, "K_SPACE")  # pause: the step view is on (V)
            press(app, "K_b")  # the bound
            press(app, "K_PERIOD", 2)  # one tick
            self.save(app, "step_view_box_robot_bottom_left", size)
        finally:
            app.close()
        app = make_app("assignment_kf", size)
        try:
            tick_to(app, 20.6)
            app.run(app.frames + 1)
            press(app, "K_SPACE")
            press(app, "K_b")
            press(app, "K_PERIOD", 2)
            self.save(app, "step_view_box_assignment_kf", size)
        finally:
            app.close()
        app = make_app("default", size, ["ekf", "dead_reckoning"], autopilot=False)
        try:
            x0, y0, x1, y1 = app.session.scenario.world.bounds
            app.session.command({"kind": "kidnap", "pose": [(x0 + x1) / 2, y1 - 1.0, math.pi / 2]})
            app.run(2)
            press(app, "K_w")
            press(app, "K_w")
            while "BUMPER" not in app.banner_text and app.frames < 2000:
                app.run(app.frames + 1)
            app.run(app.frames + 2)
            self.save(app, "bumper_banner_robot_at_top", size)
        finally:
            app.close()

    # --- a replay's banner after a seek -----------------------------------------------------
    def shot_replay_seek(self, size) -> None:
        from beacon_sim.app.replay import ReplayApp
        from beacon_sim.core.scenario import load_scenario
        from beacon_sim.io.recording import load_recording
        from beacon_sim.runs.live import Session
        from beacon_sim.runs.recorder import Recorder
        from beacon_sim.runs.replay import ReplaySession

        filters = ["ekf", "dead_reckoning"]
        path = self.out / f"kidnap_{size[0]}x{size[1]}.jsonl"
        path.unlink(missing_ok=True)  # an earlier review's (the recorder would pick a new name)
        sc = load_scenario("default")
        live = Session(sc, filters, 3, {}, Recorder(path, sc, 3, filters, {}))
        live.toggle_autopilot()
        for t in range(1, 301):
            if t == 250:
                live.command({"kind": "kidnap", "pose": [8.0, 5.0, 2.0]})
            live.tick()
        live.close()
        app = ReplayApp(ReplaySession(load_recording(path), filters), size=size, scripted=True)
        try:
            while app.session.sim.tick < 252 and app.frames < 5000:
                app.run(app.frames + 1)
            self.save(app, "replay_kidnap_banner", size)
            press(app, "K_LEFT", 3)  # seek 5 s back
            self.save(app, "replay_after_seek_no_banner", size)
        finally:
            app.close()

    # --- colours, lost beliefs, readings, the sensor disc -----------------------------------
    def shot_world(self, size) -> None:
        from beacon_sim.app.estimate_layer import ellipse_diameter

        for item, scenario, t in (("slam_bearing_only_two_colours", "slam_bearing_only", 30.0),
                                  ("corridor_misses_apart_from_wall_hits", "corridor", 12.0),
                                  ("two_rooms_sensor_disc_clipped", "two_rooms", 20.0)):
            app = make_app(scenario, size)
            try:
                tick_to(app, t)
                app.run(app.frames + 1)
                self.save(app, item, size)
            finally:
                app.close()
        app = make_app("default", size, ["ekf", "dead_reckoning"])
        try:
            s = app.session
            x0, y0, x1, y1 = s.scenario.world.bounds
            across = math.hypot(x1 - x0, y1 - y0)
            while s.time < 900.0:
                tick_to(app, s.time + 5.0)
                est = s.estimate("dead_reckoning")
                if est is not None and not ellipse_diameter(est[1]) <= across:
                    break
            app.run(app.frames + 1)
            self.save(app, "lost_belief_dead_reckoning", size)
        finally:
            app.close()

    # --- panels -----------------------------------------------------------------------------
    def shot_team(self, size) -> None:
        app = make_app("team_sparse", size)
        try:
            tick_to(app, 20.0)
            app.run(app.frames + 1)
            self.save(app, "team_panel_footer", size)
        finally:
            app.close()

    def shot_mrclam(self, size) -> None:
        data = Path(os.environ.get("BEACON_SIM_MRCLAM", "") or "-")
        folder = next((p for p in sorted(data.glob("Dataset*")) if p.is_dir()), data)
        if not folder.is_dir():
            print("BEACON_SIM_MRCLAM names no MRCLAM folder: mrclam_window_size skipped", flush=True)
            return
        from beacon_sim.cli.main import main

        path = self.out / name_of("mrclam_window_size", size)
        status = main(["mrclam", str(folder), "--robot", "1", "--duration", "120", "--frames",
                       "2400", "--screenshot", str(path), "--size", f"{size[0]}x{size[1]}"])
        assert status == 0 and path.exists(), status
        self.saved.append(path)
        print(path, flush=True)

    # --- the bound --------------------------------------------------------------------------
    def shot_bound(self, size) -> None:
        app = make_app("assignment_kf", size)
        try:
            press(app, "K_b")
            tick_to(app, 18.2)
            app.run(app.frames + 1)
            self.save(app, "kf_inside_bound_assignment_kf_blind", size)
        finally:
            app.close()

    # --- F12 --------------------------------------------------------------------------------
    def shot_f12(self, size) -> None:
        app = make_app("assignment_kf", size)
        here = Path.cwd()
        work = self.out / f"f12_{size[0]}x{size[1]}"
        shutil.rmtree(work, ignore_errors=True)  # an earlier review's files
        work.mkdir()
        os.chdir(work)  # F12 saves under ./screenshots/
        try:
            tick_to(app, 5.0)
            app.run(app.frames + 1)
            app.flash("KIDNAPPED  (a banner on the screen when F12 is pressed)")
            app.run(app.frames + 1)
            press(app, "K_F12")
            press(app, "K_F12")  # a quick second press: a new file, no "saved" banner in it
            files = sorted((work / "screenshots").glob("*.png"), key=lambda f: (len(f.name), f.name))
            assert len(files) == 2, files
            for k, f in enumerate(files):
                dest = self.out / name_of(f"f12_saved_file_no_banner_{k + 1}", size)
                shutil.copy(f, dest)
                self.saved.append(dest)
                print(dest, flush=True)
            self.save(app, "f12_window_saved_banner", size)
        finally:
            os.chdir(here)
            app.close()


def main() -> None:
    groups: dict[str, Callable] = {n[len("shot_"):]: f for n, f in vars(Review).items()
                                   if n.startswith("shot_")}  # in the order written
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", help="folder for the PNGs (default: a new folder under the "
                   "system's temporary directory)")
    p.add_argument("--only", nargs="*", choices=sorted(groups), help="these groups only")
    p.add_argument("--sizes", nargs="*", default=[f"{w}x{h}" for w, h in SIZES],
                   help="window sizes WxH (default: 1024x768 1920x1080)")
    args = p.parse_args()
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="screen_review_"))
    checkout = Path(__file__).resolve().parent.parent
    if out.resolve().is_relative_to(checkout):
        p.error(f"--out {out} is inside the checkout: give a folder outside it")
    out.mkdir(parents=True, exist_ok=True)
    review = Review(out.resolve())
    for size_text in args.sizes:
        size = tuple(int(v) for v in size_text.split("x"))
        for name in args.only or groups:
            getattr(review, f"shot_{name}")(size)
    print(f"{len(review.saved)} pictures in {out}")


if __name__ == "__main__":
    main()
