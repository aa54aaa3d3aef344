"""What each key and mouse binding of the window does: ``App.act`` dispatches an action of
``controls.TABLES`` to its ``act_<action>`` method here (``toggle3`` -> ``act_toggle(3)``); a
driving key drives. tests/app/test_app_keys_doc.py holds every binding to a method.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import pygame

from beacon_sim.app.display import display_surface
from beacon_sim.app.distance_layer import distance_sensor
from beacon_sim.app.loop import StepClock
from beacon_sim.app.render import ShowOptions, View
from beacon_sim.evaluation.live_bound import LiveBound
from beacon_sim.runs.live import Session

#: How long a banner (what an action or an event did) stays on the world [s].
BANNER_S = 2.5
QUIT_CONFIRM_S = 3.0  # a second Q or Esc within this time quits [s]
DRIVE_KEYS = {"faster": "w", "slower": "s", "left": "a", "right": "d", "stop": "x"}


class WindowActions:
    """The window's actions (``window.App`` is made of them)."""

    # What the actions change, all set up by the window (window.App.__init__).
    session: Session
    clock: StepClock
    show: ShowOptions
    view: View
    screen: pygame.Surface
    bound: LiveBound | None
    help: bool
    running: bool
    now: float  # the window's clock [s]
    quit_armed_until: float
    banner_text: str
    banner_until: float
    world_version: int

    def _layout(self, size) -> None:
        raise NotImplementedError  # the window lays itself out (window.App)

    def save_screenshot(self, path, present: bool = False) -> None:
        raise NotImplementedError  # the window saves itself (window.App)

    def act(self, action: str) -> None:
        """Do one action of the binding table (``controls.TABLES``): the method
        ``act_<action>`` (``toggle3`` -> ``act_toggle(3)``); a driving key drives."""
        if action in DRIVE_KEYS:
            self.session.drive(DRIVE_KEYS[action])
            return
        name, number = action.rstrip("0123456789"), action[len(action.rstrip("0123456789")):]
        handler = getattr(self, f"act_{name}", None)
        if handler is None:
            raise ValueError(f"no handler for the action {action!r}")
        handler(int(number)) if number else handler()

    # --- the actions (one per binding of controls.py; tests/app/test_app_keys_doc.py) ----------
    def act_next_robot(self) -> None:
        self.flash(f"driving {self.session.next_robot()}")

    def act_autopilot(self) -> None:
        self.session.toggle_autopilot()
        if not self.session.has_autopilot:
            self.flash("this scenario has no autopilot")

    def act_pause(self) -> None:
        self.clock.toggle_pause()

    def act_step(self) -> None:
        self.clock.single_step()

    def act_speed_up(self) -> None:
        self.clock.faster()

    def act_speed_down(self) -> None:
        self.clock.slower()

    def act_kidnap_random(self) -> None:
        self.session.command({"kind": "kidnap"})

    def act_reset(self) -> None:
        self.session.command({"kind": "reset"})
        self.clear_trails()
        self.flash("filters reset")

    def act_global_reset(self) -> None:
        self.session.command({"kind": "global_reset"})
        self.clear_trails()
        self.flash(self.global_reset_text())

    def act_toggle(self, number: int) -> None:
        """Show / hide filter ``number`` (1-9, in the panel's order)."""
        names = self.session.names
        if number - 1 < len(names):
            self.session.command({"kind": "toggle", "filter": names[number - 1]})

    def act_particles(self) -> None:
        self.show.particles = not self.show.particles

    def act_trails(self) -> None:
        self.show.trails = not self.show.trails

    def act_ellipses(self) -> None:
        self.show.ellipses = not self.show.ellipses

    def act_chart(self) -> None:
        self.show.chart = not self.show.chart
        self._layout(self.screen.get_size())

    def act_step_view(self) -> None:
        self.show.step = not self.show.step
        if self.show.step and not self.clock.paused:
            self.flash("step view: pause (Space), then . steps one tick")

    def act_bound(self) -> None:
        self.show.bound = not self.show.bound
        if self.show.bound and (self.bound is None or self.bound.tick < 0):
            self.flash("no bound here: it is built from the start of a run")

    def act_field(self) -> None:
        self.show.field = not self.show.field

    def act_hdop(self) -> None:
        self.show.hdop = not self.show.hdop
        if self.show.hdop and distance_sensor(self.session.scenario.sensors) is None:
            self.flash("no HDOP here: the scenario has no range, tdoa or tdoa_fix sensor")

    def act_fit(self) -> None:
        self.view.fit()

    def act_screenshot(self) -> None:
        """F12: the window as it is, without the banner, saved to a new file under
        ``screenshots/`` (:func:`screenshot_path`)."""
        path = screenshot_path(self.session.scenario.name)
        banner, self.banner_until = self.banner_until, -1.0  # no banner in the picture
        try:
            self.save_screenshot(path, present=True)
        finally:
            self.banner_until = banner
        self.flash(f"saved {path}")

    def act_help(self) -> None:
        self.help = not self.help

    def act_quit(self) -> None:
        """Q sits beside W and A: one press only asks."""
        if self.now < self.quit_armed_until:
            self.running = False
        else:
            self.quit_armed_until = self.now + QUIT_CONFIRM_S
            self.flash("Quit? Press Q or Esc again")

    def act_clear_trails(self) -> None:
        self.clear_trails()

    def act_fullscreen(self) -> None:
        try:
            pygame.display.toggle_fullscreen()
        except pygame.error as exc:
            self.flash(f"fullscreen: {exc}")
        self.screen = display_surface()
        self._layout(self.screen.get_size())

    def global_reset_text(self) -> str:
        """What G did, filter by filter: a uniform belief where the filter supports one; a
        Gaussian (one peak) cannot spread over the room and is left as it was."""
        filters = getattr(self.session, "filters", {})
        spread = [n for n, f in filters.items() if getattr(f, "supports_global", False)]
        kept = [n for n in filters if n not in spread]
        parts = []
        if spread:
            parts.append(f"global belief: {', '.join(spread)} spread over the room")
        if kept:
            parts.append(f"{', '.join(kept)} cannot (one Gaussian peak): unchanged")
        return "; ".join(parts) or "global belief: no filter to reset"

    def clear_trails(self) -> None:
        """Forget every trail (the truth's and the filters'), keep the current points."""
        self.world_version += 1
        self.session.clear_trails()

    def kidnap_at(self, start_px, end_px) -> None:
        """Left click: kidnap to the clicked point; a drag sets the heading (else keep it)."""
        xy = self.view.to_world(np.asarray(start_px, dtype=float))
        dx, dy = end_px[0] - start_px[0], end_px[1] - start_px[1]
        theta = math.atan2(-dy, dx) if math.hypot(dx, dy) > 8 else float(self.session.true_pose[2])
        self.session.command({"kind": "kidnap", "pose": [float(xy[0]), float(xy[1]), theta]})

    def flash(self, text: str) -> None:
        self.banner_text = text
        self.banner_until = self.now + BANNER_S


#: Where F12 saves (under the current directory), as recordings go to ``recordings/``.
SCREENSHOTS_DIR = "screenshots"


def screenshot_path(scenario_name: str) -> Path:
    """``screenshots/<scenario>_<YYYYmmdd-HHMMSS>.png``, with ``-2``, ``-3``, ... when that
    name is taken (two presses in one second): never an earlier picture overwritten."""
    safe = "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in scenario_name) or "window"
    base = Path(SCREENSHOTS_DIR) / f"{safe}_{time.strftime('%Y%m%d-%H%M%S')}"
    path, n = base.with_suffix(".png"), 2
    while path.exists():
        path = Path(f"{base}-{n}.png")
        n += 1
    return path
