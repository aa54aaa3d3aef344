"""``beacon-sim play``: the window. Drive with WASDX and watch every filter's belief live.

The frame: events -> actions (from the one table in ``controls``) -> as many fixed
simulation ticks as the clock allows (``loop.StepClock``) -> draw the world and the HUD.
With ``--frames N`` each frame counts as exactly 1/60 s and nothing waits, so a scripted
session (and its screenshot) is the same on every machine.
"""

from __future__ import annotations

import math
import os
import signal
import sys
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import astuple, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pygame

from beacon_sim.app import controls, distance_layer, palette
from beacon_sim.app.assets import load_fonts, ui_scale, window_icon
from beacon_sim.app.framebuffer import choose_framebuffer
from beacon_sim.app.heap import HeapSettler
from beacon_sim.app.hud import Hud
from beacon_sim.app.loop import StepClock
from beacon_sim.app.pace import fps_of
from beacon_sim.app.render import PHASES, ShowOptions, View, WorldRenderer
from beacon_sim.app.strip import StripChart
from beacon_sim.app.view import world_rect
from beacon_sim.core.files import atomic_write
from beacon_sim.core.scenario import Scenario
from beacon_sim.core.team import TeamStep
from beacon_sim.core.team_scenario import TeamScenario
from beacon_sim.core.types import Step
from beacon_sim.evaluation.live_bound import LiveBound
from beacon_sim.hosting.runner import note_user_interrupt
from beacon_sim.runs.live import Session, make_recorder

if TYPE_CHECKING:  # imported where used: the window opens without them
    from beacon_sim.app.gif import GifRecorder
    from beacon_sim.hosting.hot_reload import FilterFileWatcher

#: Frame time a scripted (``--frames``) session pretends each frame took [s].
SCRIPTED_FRAME_S = 1.0 / 60.0
BANNER_S = 2.5
QUIT_CONFIRM_S = 3.0  # a second Q or Esc within this time quits [s]
DRIVE_KEYS = {"faster": "w", "slower": "s", "left": "a", "right": "d", "stop": "x"}


def display_surface() -> pygame.Surface:
    """The window's surface (``set_mode`` made it; None only once the display is closed)."""
    surf = pygame.display.get_surface()
    if surf is None:
        raise pygame.error("the window's display surface is gone")
    return surf


class App:
    """The window around a :class:`Session`.

    Parameters
    ----------
    session : Session
    size : (int, int)
        Initial window size in pixels.
    scripted : bool
        Each frame counts as ``SCRIPTED_FRAME_S`` and the loop does not wait (for
        ``--frames``, tests and benchmarks).
    """

    #: Which binding table the keys, the mouse and the help overlay use (controls.TABLES);
    #: a live team's window uses ``team`` (Tab drives the next robot): :attr:`mode`.
    MODE = "play"
    #: A mode's drawing under the estimates, in the world's coordinates (the replay's smoothed
    #: tracks): ``overlay(surf, view, line_width)``, or None.
    world_overlay: Callable[[Any, Any, int], None] | None = None
    #: What draws the world (a subclass may draw more: the team window's robots).
    RENDERER: type[WorldRenderer] = WorldRenderer
    #: What draws the panel, the banner and the help.
    HUD: type[Hud] = Hud

    def __init__(self, session: Session, size=(1280, 800), scripted: bool = False,
                 recording: Path | None = None, *, watch_interval: float = 1.0):
        self.session = session
        #: Whether the window shows a team (``session.n_robots`` > 1): every robot, Tab,
        #: per-robot figures, the legend strip under the world.
        self.team_view = getattr(session, "n_robots", 1) > 1
        self.mode = "team" if self.team_view and self.MODE == "play" else self.MODE
        self.scripted = scripted
        self.recording = recording
        pygame.display.init()
        pygame.font.init()
        #: How frames reach the screen (app/framebuffer.py): X11's own framebuffer on X11
        self.framebuffer = choose_framebuffer(pygame.display.get_driver())
        self.screen = pygame.display.set_mode(size, pygame.RESIZABLE)
        self.screen.fill(palette.OUTSIDE)  # never a black window, even for a moment
        pygame.display.flip()
        title = session.team.name + " (team)" if self.team_view else session.scenario.name
        pygame.display.set_caption(f"beacon-sim: {title}")
        pygame.display.set_icon(window_icon())
        pygame.key.set_repeat(300, 50)
        styles = self.filter_styles(session.names)
        self.colours = {n: c for n, (c, _) in styles.items()}
        self.dashes = {n: d for n, (_, d) in styles.items()}
        self.clock = StepClock(session.scenario.dt)
        self.show = ShowOptions()
        self.keys = controls.KeyHandler(self.mode)
        self.help = False
        self.running = True
        self.frames = 0
        self.banner_text = ""
        self.banner_until = -1.0
        self.quit_armed_until = -1.0
        self.now = 0.0  # real (or scripted) seconds since start
        self.frame_times: deque[float] = deque(maxlen=60)
        self.drag_start: tuple[int, int] | None = None
        self.pan_from: tuple[int, int] | None = None
        self.reload_errors: dict[str, str] = {}  # filter name -> last failed reload (one line)
        self.watchers = self._make_watchers(watch_interval)
        self.ticks_this_frame = 0  # simulation ticks run in the current frame
        # Freeze the heap after frames (heap.py); run() switches it on for its loop (and
        # unfreezes at its end), so that tests which build many windows in one process do
        # not freeze each other's garbage.
        self.settle_heap = False
        # With smooth on (run() switches it on; off, every draw() draws everything, as tests
        # of the drawing expect), the world's picture is kept while nothing it shows changes
        # (world_key), and a frame that runs a tick shows the kept picture while the next
        # frame draws the new one, so no frame pays for the tick and the whole world's
        # drawing (results are unchanged: only the picture comes a frame later).
        self.smooth = False
        self.world_version = 0  # bumped by anything the key cannot see (cleared trails...)
        self._world: tuple[tuple, int] | None = None  # the key of the picture in _canvas
        self._canvas: pygame.Surface | None = None  # the world is drawn here, then blitted
        # a half-drawn picture: its key, the phases generator, the steps done
        self._pending: tuple[tuple, int, Any, int] | None = None
        self.world_stale = False  # the screen shows the world one tick behind the session
        # the key of the world's picture on the screen, untouched by anything drawn over it
        # since (a banner, the help...); None when unknown
        self._on_screen: tuple[tuple, int] | None = None
        self._previous_ticks = 0  # ticks run in the previous frame
        self.tick_cpu = 0.0  # CPU time of this frame's ticks [s]
        self.phase_cpu = [0.0] * PHASES  # CPU time of each drawing step [s], smoothed
        self.blit_cpu = 0.0  # CPU time of putting the world's picture on the screen [s]
        self.gif: GifRecorder | None = None  # offered every frame after drawing (--gif)
        self.bound: LiveBound | None = None  # the PCRB along the true path (B)
        if isinstance(session, Session) and not self.team_view:
            self.bound = LiveBound(session.scenario)
            session.on_step.append(self.bound.feed)
        self.chart = StripChart(session.names, session.scenario.dt)
        self.pace = DeliveredSpeed()
        self.heap = HeapSettler()  # keeps full garbage collections out of the frames (heap.py)
        self.chart_rect: pygame.Rect | None = None
        # the world's view [m -> px]; _layout gives it its area (and on every resize)
        self.view = View(session.scenario.world.bounds, (0, 0, 1, 1))
        self._layout(self.screen.get_size())

    def filter_styles(self, names: list[str]) -> dict[str, tuple]:
        """``(colour, dash pattern)`` per filter name (``runs/styles.py``, by kind; a team's
        filters by team kind)."""
        if self.team_view:
            return palette.team_filter_styles(names)
        return palette.filter_styles(names)

    # --- hot reload -----------------------------------------------------------------------
    def _make_watchers(self, interval: float) -> dict[str, FilterFileWatcher]:
        """A file watcher for every filter given as ``path.py:Class``, on the window's clock
        (``self.now``: real seconds, or 1/60 s per frame when scripted)."""
        from beacon_sim.hosting.hot_reload import FilterFileWatcher
        from beacon_sim.hosting.loading import filter_display_name

        s = self.session
        out: dict[str, FilterFileWatcher] = {}
        if not isinstance(s, Session):  # a finished run played back: nothing to reload
            return out
        for spec, name in zip(s.specs, s.names, strict=True):
            if not spec.rpartition(":")[0].endswith(".py"):
                continue
            assert s.seed is not None  # Session.__post_init__ chose it
            w = FilterFileWatcher(spec, s.scenario, s.seed, name=name,
                                  params=s.params.get(filter_display_name(spec)),
                                  interval=interval, clock=lambda: self.now)
            if w.watchable:
                out[name] = w
        return out

    def poll_watchers(self) -> None:
        """Reload the filters whose file changed: swap the new one in, or show the error and
        keep the previous version (traceback to stderr)."""
        for name, w in self.watchers.items():
            res = w.poll()
            if res.new_filter is not None:
                how = self.swap_filter(name, res.new_filter)
                self.reload_errors.pop(name, None)
                self.flash(f"{res.message}; {how}")
            elif res.error is not None:
                self.reload_errors[name] = res.error
                self.flash(res.error)
                if res.traceback:
                    print(res.traceback, file=sys.stderr, end="")
                print(f"beacon-sim: {res.error}", file=sys.stderr)

    # --- layout ---------------------------------------------------------------------------
    def _layout(self, size) -> None:
        W, H = size
        self.world_version += 1
        self.ui_scale = ui_scale(W, H)
        self.fonts = load_fonts(H, W)
        self.renderer = self.RENDERER(self.fonts)
        self.hud = self.HUD(self.fonts, self.mode)
        # The panel scales with the text (340 px at 1280x800); the room gets most of the width.
        pw = int(min(340 * self.ui_scale, 0.4 * W))
        self.panel_rect = pygame.Rect(W - pw, 0, pw, H)
        area = self.world_area(W - pw, H)
        if self.show.chart:  # the strip chart takes the bottom ~30 % of the world's area
            ax, ay, aw, ah = area
            ch = max(int(ah * 0.3), 120)
            self.chart_rect = pygame.Rect(ax, ay + ah - ch, aw, ch)
            area = (ax, ay, aw, ah - ch)
        else:
            self.chart_rect = None
        self.view.set_area(area)

    def world_area(self, width: int, height: int) -> tuple[int, int, int, int]:
        """The part of the window (x, y, w, h) [px] the world is drawn in, left of the panel;
        on a team less the legend's strip under it (sized for every filter, shown or hidden,
        so the world does not jump when one is hidden)."""
        if self.team_view:
            return (0, 0, width, height - self.hud.legend_height(width, self.session.names))
        return (0, 0, width, height)

    def legend_area(self) -> pygame.Rect:
        """A team's strip under the world view the legend is drawn in."""
        x, y, w, h = self.view.area
        return pygame.Rect(x, y + h, w, self.hud.legend_height(w, self.session.names))

    # --- events ---------------------------------------------------------------------------
    def handle(self, event) -> None:
        """One pygame event: keys through the binding table, the mouse, window changes."""
        if event.type == pygame.QUIT:
            self.running = False
        elif event.type in (pygame.KEYDOWN, pygame.KEYUP):
            for action in self.keys.actions(event):
                self.act(action)
        elif event.type == pygame.MOUSEBUTTONDOWN:
            clicked = controls.mouse_action(event.button, self.mode)
            if clicked == "kidnap_click" and pygame.Rect(self.view.area).collidepoint(event.pos) \
                    and not self.over_the_world(event.pos):
                self.drag_start = event.pos
            elif clicked == "pan":
                self.pan_from = event.pos
        elif event.type == pygame.MOUSEBUTTONUP:
            clicked = controls.mouse_action(event.button, self.mode)
            if clicked == "kidnap_click" and self.drag_start is not None:
                self.kidnap_at(self.drag_start, event.pos)
                self.drag_start = None
            elif clicked == "pan":
                self.pan_from = None
        elif event.type == pygame.MOUSEMOTION and self.pan_from is not None:
            self.view.pan(event.pos[0] - self.pan_from[0], event.pos[1] - self.pan_from[1])
            self.pan_from = event.pos
        elif event.type == pygame.MOUSEWHEEL:
            self.view.zoom(1.15 ** event.y, pygame.mouse.get_pos())
        elif event.type in (pygame.VIDEORESIZE, pygame.WINDOWSIZECHANGED):
            self.screen = display_surface()
            self._layout(self.screen.get_size())

    def robot_box(self) -> pygame.Rect:
        """The driven robot on the screen, with a margin [px]: what a banner must not cover."""
        pose = self.session.true_pose
        c = self.view.to_px(np.asarray(pose[:2], dtype=float))
        r = max(self.session.scenario.robot_radius * self.view.scale, 14.0) * 2.0
        return pygame.Rect(int(c[0] - r), int(c[1] - r), int(2 * r), int(2 * r))

    def over_the_world(self, pos) -> bool:
        """Whether the pixel ``pos`` is on something drawn over the world (the magnifier, the
        note of switched-off filters): a click there is not a kidnap to the point under it."""
        boxes = []
        mag = self.renderer.last_magnifier
        if mag is not None:
            boxes.append(mag.get("block", mag["rect"]))
        if getattr(self.hud, "off_box", None) is not None and self.switched_off_lines():
            boxes.append(self.hud.off_box)
        return any(pygame.Rect(b).collidepoint(pos) for b in boxes)

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
        if self.show.hdop and distance_layer.distance_sensor(self.session.scenario.sensors) is None:
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

    # --- the frame ------------------------------------------------------------------------
    def frame(self, real_dt: float) -> None:
        """Handle events, run the simulation ticks due, draw."""
        self.now += real_dt
        for event in pygame.event.get():
            self.handle(event)
        self.poll_watchers()  # a filter object is swapped here, between ticks
        self.ticks_this_frame = self.ticks_due(real_dt)
        c0 = time.process_time()
        for _ in range(self.ticks_this_frame):
            self.after_tick(self.session.tick())
        self.tick_cpu = time.process_time() - c0
        self.pace.sample(self.now, self.session.time, self.clock.speed, self.clock.paused)
        self.draw()
        if self.gif is not None:
            self.gif.offer(self.screen)
        self.frames += 1
        self._previous_ticks = self.ticks_this_frame
        if self.settle_heap:
            self.heap.offer(self.now, self.ticks_this_frame > 0)

    def after_tick(self, step) -> None:
        """What the window does after each tick: the strip chart, banners for events."""
        self.chart.record(self.session)
        if isinstance(step, TeamStep):
            for name, s in zip(self.session.robot_names, step.steps, strict=True):
                self.announce(s.events, who="the robot" if len(step.steps) == 1 else name)
        else:
            self.announce(step.events if isinstance(step, Step) else step)

    def announce(self, events, who: str = "the robot") -> None:
        """A banner for the events of a tick (bump, kidnap, the start of a blackout...)."""
        for ev in events:
            if ev.kind == "bump":
                self.flash(f"BUMPER: {who} hit the wall and stopped (v = 0)")
            elif ev.kind == "kidnap":
                self.flash(f"KIDNAPPED  ({ev.detail})" if who == "the robot"
                           else f"{who.upper()} KIDNAPPED  ({ev.detail})")
            elif ev.kind.endswith("_start"):
                self.flash(ev.kind[: -len("_start")].replace("_", " ").upper()
                           + (f": {ev.detail}" if ev.detail else ""))

    def ticks_due(self, real_dt: float) -> int:
        """How many simulation ticks to run this frame."""
        return self.clock.advance(real_dt)

    def swap_filter(self, name: str, flt) -> str:
        """Replace a running filter (hot reload of a student's file); says how it caught up."""
        self.world_version += 1
        return self.session.replace_filter(name, flt)

    def draw(self) -> None:
        surf = self.screen
        drag = None
        if self.drag_start is not None:
            drag = (self.drag_start, pygame.mouse.get_pos())
        steps = self.step_view()
        dashes = dict(self.dashes)
        for name in steps:  # the step view: the posterior solid, whatever the kind's style
            dashes[name] = None
        bound = self.bound if (self.show.bound and self.bound is not None
                               and self.bound.valid) else None
        self.renderer.bound_cov = bound.P if bound is not None else None  # the magnifier's

        overlay = self.world_overlay

        def extra(surf, view, lw):
            if bound is not None:
                self.renderer.bound(surf, view, self.session.true_pose, bound.P)
            if steps:
                self.renderer.priors(surf, view, steps, self.colours, self.session.used_ids())
            if overlay is not None:
                overlay(surf, view, lw)

        key = self.world_key(drag, steps, bound)
        args = (self.view, self.session, self.colours, self.show, drag, dashes,
                extra if (steps or bound is not None or overlay is not None) else None)
        shown = None  # the key of the world's picture left on the screen
        if key is None:
            self.renderer.draw(surf, *args)
            self.world_stale = False
        else:
            shown = self.draw_world(surf, key, args)
        info = {"speed": self.clock.speed, "paused": self.clock.paused, "mode": self.mode,
                "delivered": self.pace.factor,
                "fps": fps_of(np.array(self.frame_times)), "recording": self.recording,
                "reload_errors": self.reload_errors,
                "bound": bound.sigmas() if bound is not None else None}
        self.hud.panel(surf, self.panel_rect, self.session, self.colours, info)
        if self.chart_rect is not None:
            self.chart.draw(surf, self.chart_rect, self.fonts, self.colours, self.dashes,
                            self.session.visible, now=self.now, busy=self.ticks_this_frame > 0)
        if steps or bound is not None:
            self.hud.step_legend(surf, pygame.Rect(self.view.area), self.session, bool(steps),
                                 bound is not None, avoid=self.renderer.axis_rects,
                                 world=world_rect(self.view))
        off = self.switched_off_lines()
        if off:
            mag = self.renderer.last_magnifier
            self.hud.switched_off(surf, pygame.Rect(self.view.area), off, avoid=self.renderer.axis_rects,
                                  keep_clear=[mag.get("block", mag["rect"])] if mag else [])
        if self.now < self.banner_until:
            self.hud.banner(surf, pygame.Rect(self.view.area), self.banner_text, self.robot_box())
        self.draw_extra(surf)
        if self.help:
            self.hud.help(surf)
        # Nothing drawn over the world: the next frame may leave its picture as it is.
        overlaid = (bool(steps) or bound is not None or self.now < self.banner_until or self.help
                    or bool(off))
        self._on_screen = None if overlaid or self.team_view \
            or type(self).draw_extra is not App.draw_extra else shown
        pygame.display.flip()

    def switched_off_lines(self) -> list[tuple[str, tuple]]:
        """A line ``(text, colour)`` per switched-off filter, for the note on the world: why,
        and whether R brings it back (a filter that was built; one that could not be built
        stays off)."""
        out = []
        run = getattr(self.session, "filters_run", None)
        for name in self.session.names:
            why = self.session.status[name].failed
            if not why:
                continue
            built = run is not None and run.track(name, 0).filter is not None
            out.append((f"{name} switched off: {why}" + ("  (R: back on)" if built else ""),
                        self.colours[name]))
        return out

    def draw_world(self, surf: pygame.Surface, key: tuple[tuple, int],
                   args: tuple) -> tuple[tuple, int]:
        """The world's picture for ``key`` (see :meth:`world_key`) onto ``surf``: the one kept
        when nothing changed; else drawn into the canvas (``WorldRenderer.phases``) and kept.
        A frame that runs a tick after a frame that did not (:meth:`defer_tick`) shows the
        kept picture and draws the first layers of the new one, as many as keep it lighter
        than the next frame, which draws the rest and shows it. The kept picture is not
        blitted when the screen still holds it (:attr:`_on_screen`). Returns the key of the
        picture shown."""
        area = pygame.Rect(self.view.area).clip(surf.get_rect())
        canvas = self._canvas
        if canvas is None or canvas.get_size() != surf.get_size():
            canvas = self._canvas = pygame.Surface(surf.get_size(), 0, surf)
            self._world = None
            if self._pending is not None:  # begun on the old canvas
                self._pending[2].close()
                self._pending = None
        pending, self._pending = self._pending, None
        if pending is not None:
            if pending[:2] == key:
                self._run_phases(pending[2], pending[3], PHASES)  # the rest, same state
                self._world = key
            else:
                pending[2].close()
        if self._world == key:
            self.world_stale = False
            if self._on_screen == key:
                return key  # on the screen already
        elif self._world is not None and self._world[0] == key[0] and self.defer_tick():
            shown = self._world
            if self._on_screen != shown:
                surf.blit(canvas, area, area)  # the previous tick's picture, once more
            self.world_stale = True
            phases = self.renderer.phases(canvas, *args)
            # A layer now when that lowers the heavier of this frame (the tick and the layers
            # so far) and the next (the other layers and showing the picture).
            now, later, done = self.tick_cpu, sum(self.phase_cpu) + self.blit_cpu, 0
            while done < PHASES and now + self.phase_cpu[done] < later:
                now += self.phase_cpu[done]
                later -= self.phase_cpu[done]
                done += 1
            self._pending = (*key, phases, self._run_phases(phases, 0, done))
            self._world = None
            return shown
        else:
            self._run_phases(self.renderer.phases(canvas, *args), 0, PHASES)
            self._world, self.world_stale = key, False
        c0 = time.process_time()
        surf.blit(canvas, area, area)
        self.blit_cpu += 0.2 * (time.process_time() - c0 - self.blit_cpu)
        return key

    def _run_phases(self, phases, first: int, stop: int) -> int:
        """Run the steps ``first`` .. ``stop - 1`` of a ``WorldRenderer.phases`` generator,
        folding each one's CPU time into ``phase_cpu`` (a slow moving average); returns the
        step to go on from."""
        for i in range(first, stop):
            c0 = time.process_time()
            try:
                next(phases)
            except StopIteration:
                return PHASES
            finally:
                self.phase_cpu[i] += 0.2 * (time.process_time() - c0 - self.phase_cpu[i])
        return stop

    def world_key(self, drag, steps, bound) -> tuple[tuple, int] | None:
        """What the world's picture depends on, as (everything but the tick, the tick); None
        where it is not kept (smooth off; a replay: it draws every frame). Between
        two ticks a live session's world changes only through what the first part holds."""
        s = self.session
        if not self.smooth or type(s) is not Session:
            return None
        tracks: tuple[object, ...] = tuple((n, id(t.filter), bool(t.failed))
                                           for n, t in s.runner.tracks.items())
        if self.team_view:  # the team filters and the robot the keys drive (its halo, its tag)
            tracks += (s.driven, *((n, id(t.filter), bool(t.failed)) for n, t in s.joint.tracks.items()))
        static = (self.world_version, id(s), self.view.key, self.screen.get_size(),
                  astuple(self.show), tuple(s.visible.items()), tracks,
                  tuple(bool(st.failed) for st in s.status.values()), drag, tuple(steps),
                  bound is not None, self.clock.paused, tuple(self.colours.items()))
        return static, s.tick_count

    def defer_tick(self) -> bool:
        """Show this frame's ticks on the next frame (keep the previous picture now): when
        smooth is on, this frame ran ticks and the previous one did not (so the next frame
        is free to draw; at high speed, with ticks every frame, every frame draws)."""
        return self.smooth and self.ticks_this_frame > 0 and self._previous_ticks == 0

    def step_view(self) -> dict[str, tuple]:
        """Filter name -> (prior, posterior) of the last tick, each (mean, cov), for the
        visible Gaussian filters, while paused with the step view on; else empty."""
        s = self.session
        if not (self.show.step and self.clock.paused and self.show.ellipses
                and hasattr(s, "predict_update")):
            return {}
        out = {}
        for name in s.names:
            if s.visible[name] and not s.status[name].failed:
                pu = s.predict_update(name)
                if pu is not None:
                    out[name] = pu
        return out

    def draw_extra(self, surf) -> None:
        """Anything a mode adds under the help overlay: a team's legend of the world's lines
        (the replay adds its timeline)."""
        if self.team_view:
            self.hud.world_legend(surf, self.legend_area(), self.session, self.colours,
                                  self.dashes, self.renderer.lw)

    def show_present(self) -> None:
        """When the screen shows the world a tick behind (smooth), draw the present one."""
        if self.world_stale:
            smooth, self.smooth = self.smooth, False
            try:
                self.draw()
            finally:
                self.smooth = smooth

    def save_screenshot(self, path, present: bool = False) -> None:
        """The window into the PNG ``path`` (the present, not a tick behind; ``present``:
        drawn afresh, so that whatever was drawn over the world is as it is now)."""
        if present:
            self.world_stale = True
        self.show_present()
        path = Path(path)
        if path.parent and not path.parent.exists():
            path.parent.mkdir(parents=True, exist_ok=True)
        try:  # whole or not at all: a full disk leaves the previous file as it was
            with atomic_write(path, "wb", what="screenshot") as fh:
                pygame.image.save(self.screen, fh, path.name)
        except pygame.error as exc:  # a path that cannot be written: one line, exit 2
            raise OSError(0, str(exc), str(path)) from None

    def _on_signal(self, signum, frame) -> None:
        """SIGINT / SIGTERM: close the window after this frame (a filter's step is cut short
        by the runner's time limit). A second signal interrupts whatever runs (the user's
        interrupt, which the filter guard lets through); a third ends the process at once,
        after flushing the recording."""
        self._signals += 1
        if self._signals == 1:
            self.running = False
            return
        note_user_interrupt()
        if self._signals == 2:
            raise KeyboardInterrupt
        try:
            self.session.close()
        finally:
            os._exit(128 + signum)

    def run(self, max_frames: int | None = None) -> None:
        """The main loop, until quit (or ``max_frames`` frames). SIGINT and SIGTERM close the
        window as the close button does, whatever a filter does (see :meth:`_on_signal`)."""
        self._signals = 0
        # For the loop only: a later draw() draws everything, a later frame() freezes nothing.
        settle, self.settle_heap = self.settle_heap, True
        smooth, self.smooth = self.smooth, True
        previous = {}
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                previous[sig] = signal.signal(sig, self._on_signal)
        try:
            self._loop(max_frames)
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)
            self.smooth, self.settle_heap = smooth, settle
            self.heap.release()  # the loop's frozen heap is collectable again
        self.show_present()  # the last frame shows the present, not a tick behind

    def _loop(self, max_frames: int | None) -> None:
        if self.frames == 0:  # the first picture at once, before any tick (t = 0 of a run)
            pygame.event.pump()
            self.draw()
        timer = pygame.time.Clock()
        last = time.perf_counter()
        while self.running and (max_frames is None or self.frames < max_frames):
            if self.scripted:
                real_dt = SCRIPTED_FRAME_S
            else:
                timer.tick(60)
                t = time.perf_counter()
                real_dt, last = t - last, t
            t0 = time.perf_counter()
            self.frame(real_dt)
            self.frame_times.append(max(time.perf_counter() - t0, 1e-6) if self.scripted
                                    else real_dt)

    def close(self) -> None:
        self.session.close()
        pygame.display.quit()


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


class DeliveredSpeed:
    """The speed factor the simulation actually delivers: simulated seconds per second of
    the window's clock over the last :attr:`SPAN_S` (None until that long has been seen at
    one speed and running). Under load the clock drops ticks, so the panel's "x8" can be
    0.85 in truth; the panel shows this figure when it falls short."""

    SPAN_S = 2.0

    def __init__(self) -> None:
        self.samples: deque[tuple[float, float]] = deque()
        self._key: tuple | None = None

    def sample(self, now: float, sim_time: float, speed: float, paused: bool) -> None:
        """After a frame: the window's clock [s], the simulated time [s], the asked speed."""
        key = (speed, paused)
        if key != self._key or (self.samples and sim_time < self.samples[-1][1]):
            self.samples.clear()  # a new speed, a pause or a seek back: measure afresh
            self._key = key
        self.samples.append((now, sim_time))
        while len(self.samples) > 2 and now - self.samples[1][0] >= self.SPAN_S:
            self.samples.popleft()

    @property
    def factor(self) -> float | None:
        if len(self.samples) < 2 or self._key is None or self._key[1]:
            return None
        (t0, s0), (t1, s1) = self.samples[0], self.samples[-1]
        if t1 - t0 < self.SPAN_S * 0.99:
            return None
        return (s1 - s0) / (t1 - t0)


def check_display() -> None:
    """Raise ``UsageError`` (one line, exit 2) when no window can open: on Linux, no X or
    Wayland display and no SDL video driver chosen (a window would run invisibly)."""
    from beacon_sim.errors import UsageError

    if os.environ.get("SDL_VIDEODRIVER"):
        return
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY")
                                                 or os.environ.get("WAYLAND_DISPLAY")):
        raise UsageError("no display to open a window on (DISPLAY is not set); for a headless"
                         " window set SDL_VIDEODRIVER=dummy, or use beacon-sim run")
    try:
        pygame.display.init()
    except pygame.error as exc:
        raise UsageError(f"cannot open a window: {exc}") from None
    driver = pygame.display.get_driver()
    if driver in HEADLESS_DRIVERS:  # SDL fell back to drawing nowhere: DISPLAY has no server
        pygame.display.quit()
        where = os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY") or "the display"
        raise UsageError(f"cannot open a window on {where} (no display server answers there;"
                         " SDL would draw invisibly); for a headless window set"
                         " SDL_VIDEODRIVER=dummy, or use beacon-sim run")


#: SDL video drivers that show nothing; chosen only by SDL_VIDEODRIVER, never as a fallback.
HEADLESS_DRIVERS = frozenset({"offscreen", "dummy"})


@dataclass(frozen=True)
class PlayOptions:
    """What ``beacon-sim play`` opens (the command line checks and builds these)."""

    scenario: Scenario | TeamScenario  # one robot, or a team (Tab drives the next robot)
    filters: list[str]  # filter specs
    seed: int
    params: dict[str, dict[str, Any]] = field(default_factory=dict)  # ``--set`` overrides
    size: tuple[int, int] = (1280, 800)  # window [px]
    frames: int | None = None  # quit after this many frames (scripts, tests)
    screenshot: str | None = None  # save the last frame here (PNG)
    record: bool = True
    autopilot: bool = False
    paused: bool = False  # start paused (Space runs, . steps)
    speed: float | None = None  # start at this speed factor (nearest of loop.SPEEDS)
    gif: str | None = None  # also write the session as an animated GIF here
    gif_width: int | None = 640  # the GIF's width [px]; None: the window's
    foxglove: int | None = None  # also stream the session to Foxglove on this port (127.0.0.1)


def play(options: PlayOptions) -> int:
    """Open the window on a live session (one robot or a team); returns the exit status."""
    o = options
    check_display()
    recorder, rec_path = (None, None)
    if o.record:
        recorder, rec_path = make_recorder(o.scenario, o.seed, o.filters, o.params)
    session = Session(o.scenario, o.filters, o.seed, o.params, recorder)
    if o.autopilot:
        session.toggle_autopilot()
    os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
    app = App(session, o.size, scripted=o.frames is not None, recording=rec_path)
    from beacon_sim.app.foxglove import stream

    live = stream(session, o.foxglove)
    try:
        run_window(app, o)
    finally:
        if live is not None:
            live.close()
    if rec_path is not None:
        print(f"recorded to {rec_path}", file=sys.stderr)
    return 0


def run_window(app: App, options: PlayOptions) -> None:
    """Run an opened window as the command line asked (paused, speed, GIF, ``--frames``),
    save ``--screenshot`` from its last frame and the GIF, and close it."""
    o = options
    start(app, o.paused, o.speed, o.gif, o.gif_width)
    try:
        app.run(o.frames)
        if o.screenshot:
            app.save_screenshot(o.screenshot)
        finish_gif(app)
    finally:
        app.close()


def start(app: App, paused: bool = False, speed: float | None = None, gif: str | None = None,
          gif_width: int | None = 640) -> None:
    """The command line's starting state: paused, the speed factor, a GIF being captured
    (``gif_width`` [px] wide; None: as wide as the window)."""
    if paused:
        app.clock.paused = True
    if speed is not None:
        app.clock.set_speed(speed)
    if gif:
        from beacon_sim.app.gif import GifRecorder

        app.gif = GifRecorder(gif, width=gif_width or app.screen.get_width())


def finish_gif(app: App) -> None:
    """Write the GIF the window captured (if any) and say where, how many frames, how big."""
    if app.gif is None:
        return
    n = app.gif.save()
    size = app.gif.size  # set by the first frame captured
    if not n or size is None:
        print(f"beacon-sim: no frame captured, {app.gif.path} not written", file=sys.stderr)
        return
    kb = app.gif.path.stat().st_size / 1024
    full = " (stopped capturing at the frame limit)" if app.gif.full else ""
    print(f"wrote {app.gif.path}: {n} frames of {app.gif.duration_ms} ms, {size[0]}x"
          f"{size[1]} px, {kb:.0f} KB{full}", file=sys.stderr)


__all__ = ["App", "PlayOptions", "finish_gif", "play", "run_window", "start"]
