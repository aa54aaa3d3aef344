"""The window around a session (``App``): its layout, events, ticks and frames. Drive with
WASDX and watch every filter's belief live; ``main.play`` opens it for ``beacon-sim play``,
``replay.ReplayApp`` is the same window driven by a recording.

The frame: events -> actions (from the one table in ``controls``, done by ``actions``) -> as
many fixed simulation ticks as the clock allows (``loop.StepClock``) -> draw the world
(``render``) and the HUD (``hud``). With ``--frames N`` each frame counts as exactly 1/60 s
and nothing waits, so a scripted session (and its screenshot) is the same on every machine.
"""

from __future__ import annotations

import os
import signal
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import astuple
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pygame

from beacon_sim.app import controls, palette
from beacon_sim.app.actions import WindowActions
from beacon_sim.app.ahead import DrawingAhead, TickBound
from beacon_sim.app.assets import load_fonts, ui_scale, window_icon
from beacon_sim.app.display import display_surface
from beacon_sim.app.framebuffer import choose_framebuffer
from beacon_sim.app.heap import HeapSettler
from beacon_sim.app.hud import Hud
from beacon_sim.app.loop import StepClock
from beacon_sim.app.pace import DeliveredSpeed, fps_of
from beacon_sim.app.reloading import FilterReloading
from beacon_sim.app.render import PHASES, ShowOptions, View, WorldRenderer
from beacon_sim.app.strip import StripChart
from beacon_sim.app.view import world_rect
from beacon_sim.app.world_notes import switched_off_lines
from beacon_sim.core.files import atomic_write
from beacon_sim.core.team import TeamStep
from beacon_sim.core.types import Step
from beacon_sim.hosting.runner import note_user_interrupt
from beacon_sim.runs.live import Session

if TYPE_CHECKING:  # imported where used: the window opens without it
    from beacon_sim.app.gif import GifRecorder

#: Frame time a scripted (``--frames``) session pretends each frame took [s].
SCRIPTED_FRAME_S = 1.0 / 60.0
#: Frames between ticks from which a tick's picture is drawn over three frames, not two
#: (x1 at 60 FPS: 0.05 s ticks are 3 frames apart, 0.1 s ticks 6; at x2 and faster with
#: 0.05 s ticks, at x4 with 0.1 s ticks, two frames).
SPREAD_GAP = 3


class App(WindowActions, FilterReloading):
    """The window around a :class:`Session`; its key actions are ``actions.WindowActions``,
    its hot reload ``reloading.FilterReloading``.

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
        self.ticks_this_frame = 0  # simulation ticks run (with a worker: shown) in the current frame
        # The filters on a worker thread (``runs/filter_worker``) while run() runs: None,
        # when the frames are real (not scripted); True / False to say. ``lockstep``: each
        # frame waits for the worker's ticks and shows them (what a scripted frame shows
        # without one: the same picture, for tests).
        self.filter_thread: bool | None = None
        self.lockstep = False
        self.owed_s = 0.0  # wall time not yet given to the clock while the worker catches up [s]
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
        # a half-drawn picture: its key, the phases generator, the steps done, whether a
        # frame between its tick and the one that shows it drew some of it
        self._pending: tuple[tuple, int, Any, int, bool] | None = None
        self._tick_gap = 0  # frames between the last two frames that showed ticks
        self._last_tick_frame = -1
        self._again = False  # this frame began a picture again (a tick came half way)
        self.world_stale = False  # the screen shows the world one tick behind the session
        # the key of the world's picture on the screen, untouched by anything drawn over it
        # since (a banner, the help...); None when unknown
        self._on_screen: tuple[tuple, int] | None = None
        self._previous_ticks = 0  # ticks run in the previous frame
        self.tick_cpu = 0.0  # CPU time of this frame's ticks [s]
        self.phase_cpu = [0.0] * PHASES  # CPU time of each drawing step [s], smoothed
        self.blit_cpu = 0.0  # CPU time of putting the world's picture on the screen [s]
        self.gif: GifRecorder | None = None  # offered every frame after drawing (--gif)
        self.bound = None  # the PCRB along the true path (B): an ahead.TickBound, read as a LiveBound
        if isinstance(session, Session):  # what a tick's drawing needs, computed on the worker
            session.on_worker_step.append(DrawingAhead(session))
            self.bound = None if self.team_view else TickBound(session)  # type: ignore[assignment]
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

    # --- the frame ------------------------------------------------------------------------
    def frame(self, real_dt: float) -> None:
        """Handle events, run the simulation ticks due, draw."""
        self.now += real_dt
        for event in pygame.event.get():
            self.handle(event)
        self.poll_watchers()  # a filter object is swapped here, between ticks
        self.ticks_this_frame = self.ticks_due(real_dt)
        c0 = time.thread_time()
        if getattr(self.session, "worker", None) is None:
            for _ in range(self.ticks_this_frame):
                self.after_tick(self.session.tick())
        else:  # the filters run on the worker: show the ticks it finished
            for _ in range(self.ticks_this_frame):
                self.session.tick()
            if self.lockstep:
                self.session.settle_worker()
            self.ticks_this_frame = self.session.collect(self.after_tick)
        self.tick_cpu = time.thread_time() - c0
        if self.ticks_this_frame:
            self._tick_gap, self._last_tick_frame = self.frames - self._last_tick_frame, self.frames
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
                self.flash(f"KIDNAPPED: {ev.detail}" if who == "the robot"
                           else f"{who.upper()} KIDNAPPED: {ev.detail}")
            elif ev.kind.endswith("_start"):
                self.flash(ev.kind[: -len("_start")].replace("_", " ").upper()
                           + (f": {ev.detail}" if ev.detail else ""))

    def ticks_due(self, real_dt: float) -> int:
        """How many simulation ticks to run this frame. While the filters' worker has ticks
        to finish, none: the frame's wall time is kept (``owed_s``) and given to the clock
        once it has, so a worker slower than real time slows the simulation down as filters
        run in the tick do (at most ``max_steps_per_frame`` ticks a frame, the rest of the
        time dropped; the panel's delivered speed says so), and no filter tick is skipped."""
        if getattr(self.session, "filters_behind", False):
            if not self.clock.paused:
                self.owed_s += real_dt
            return 0
        real_dt, self.owed_s = real_dt + self.owed_s, 0.0
        return self.clock.advance(real_dt)

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
        mag = self.renderer.last_magnifier
        notes = [pygame.Rect(mag.get("block", mag["rect"]))] if mag else []  # over the world
        if steps or bound is not None:
            notes.append(self.hud.step_legend(surf, pygame.Rect(self.view.area), self.session,
                                              bool(steps), bound is not None,
                                              avoid=self.renderer.axis_rects,
                                              world=world_rect(self.view)))
        off = self.switched_off_lines()
        if off:
            box = self.hud.switched_off(surf, pygame.Rect(self.view.area), off,
                                        avoid=self.renderer.axis_rects, keep_clear=notes[:1])
            notes += [box] if box is not None else []
        if self.now < self.banner_until:
            self.hud.banner(surf, pygame.Rect(self.view.area), self.banner_text, self.robot_box(),
                            keep_clear=notes)
        self.draw_extra(surf)
        if self.help:
            self.hud.help(surf)
        # Nothing drawn over the world (or the panel; a team's legend is under the world):
        # the next frame may leave it as it is.
        overlaid = (bool(steps) or bound is not None or self.now < self.banner_until or self.help
                    or bool(off))
        plain = type(self).draw_extra is App.draw_extra  # (a replay's timeline crosses the panel)
        self._on_screen = None if overlaid or not plain else shown
        self.hud.kept_panel.intact = plain and not self.help
        pygame.display.flip()

    def switched_off_lines(self) -> list[tuple[str, tuple]]:
        """A line ``(text, colour)`` per switched-off filter (``world_notes.switched_off_lines``)."""
        return switched_off_lines(self.session, self.colours)

    def draw_world(self, surf: pygame.Surface, key: tuple[tuple, int],
                   args: tuple) -> tuple[tuple, int]:
        """The world's picture for ``key`` (see :meth:`world_key`) onto ``surf``: the one kept
        when nothing changed; else drawn into the canvas (``WorldRenderer.phases``) and kept.
        A frame that runs a tick after a frame that did not (:meth:`defer_tick`) shows the
        kept picture and draws the first layers of the new one, as many as keep it lighter
        than the next frame, which draws the rest and shows it (so too when a tick comes half
        way, once in a row). When ticks are :data:`SPREAD_GAP` frames apart or more, the
        frame after the tick's may draw some of the layers too (still showing the previous
        picture), so a tick's picture costs three frames a share each, not two. The kept
        picture is not blitted when the screen still holds it (:attr:`_on_screen`). Returns
        the key of the picture shown."""
        area = pygame.Rect(self.view.area).clip(surf.get_rect())
        canvas = self._canvas
        if canvas is None or canvas.get_size() != surf.get_size():
            canvas = self._canvas = pygame.Surface(surf.get_size(), 0, surf)
            self._world = None
            if self._pending is not None:  # begun on the old canvas
                self._pending[2].close()
                self._pending = None
        pending, self._pending = self._pending, None
        self._again = again = (pending is not None and pending[:2] != key and not self._again
                               and self._on_screen is not None and self._on_screen[0] == key[0])
        if pending is not None:
            if pending[:2] == key and self._on_screen is not None and self._spread(pending):
                return self._on_screen  # the previous picture, still on the screen
            if pending[:2] == key:
                self._run_phases(pending[2], pending[3], PHASES)  # the rest, same state
                self._world = key
            else:
                pending[2].close()
        if self._world == key:
            self.world_stale = False
            if self._on_screen == key:
                return key  # on the screen already
        elif again or (self._world is not None and self._world[0] == key[0] and self.defer_tick()):
            shown = self._world or self._on_screen or key  # (again: the one on the screen)
            if self._on_screen != shown:
                surf.blit(canvas, area, area)  # the previous tick's picture, once more
            self.world_stale = True
            phases = self.renderer.phases(canvas, *args)
            # A layer now when that lowers the heavier of this frame (the tick and the layers
            # so far) and the next (the other layers and showing the picture), or the next
            # two when the frame after this one may draw some (:meth:`_spread`).
            now, later, done = self.tick_cpu, sum(self.phase_cpu) + self.blit_cpu, 0
            parts = 2 if self._tick_gap >= SPREAD_GAP else 1
            while done < PHASES and now + self.phase_cpu[done] < later / parts:
                now += self.phase_cpu[done]
                later -= self.phase_cpu[done]
                done += 1
            self._pending = (*key, phases, self._run_phases(phases, 0, done), False)
            self._world = None
            return shown
        else:
            self._run_phases(self.renderer.phases(canvas, *args), 0, PHASES)
            self._world, self.world_stale = key, False
        c0 = time.thread_time()
        surf.blit(canvas, area, area)
        self.blit_cpu += 0.2 * (time.thread_time() - c0 - self.blit_cpu)
        return key

    def _spread(self, pending) -> bool:
        """Draw some more of the ``pending`` picture and leave it pending (True) when this
        frame runs no tick, the screen still shows the previous picture, ticks come
        :data:`SPREAD_GAP` frames apart or more, and no frame did so for this picture yet:
        as many layers as keep this frame lighter than the next (the rest and the blit)."""
        if pending[4] or self.ticks_this_frame or self._tick_gap < SPREAD_GAP:
            return False
        step = done = pending[3]
        now, later = 0.0, sum(self.phase_cpu[step:]) + self.blit_cpu
        while done < PHASES and now + self.phase_cpu[done] < later:
            now += self.phase_cpu[done]
            later -= self.phase_cpu[done]
            done += 1
        if done == step:
            return False
        self._pending = (*pending[:2], pending[2], self._run_phases(pending[2], step, done), True)
        self.world_stale = True
        return True

    def _run_phases(self, phases, first: int, stop: int) -> int:
        """Run the steps ``first`` .. ``stop - 1`` of a ``WorldRenderer.phases`` generator,
        folding each one's CPU time into ``phase_cpu`` (a slow moving average); returns the
        step to go on from."""
        for i in range(first, stop):
            c0 = time.thread_time()
            try:
                next(phases)
            except StopIteration:
                return PHASES
            finally:
                self.phase_cpu[i] += 0.2 * (time.thread_time() - c0 - self.phase_cpu[i])
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
            if self.stop_filter_thread(timeout=2.0):  # a filter that hangs gives up the recording's end
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
        threaded = not self.scripted if self.filter_thread is None else self.filter_thread
        if threaded and type(self.session) is Session:  # a live session (not a replay)
            self.session.start_worker()
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
            self.stop_filter_thread()
        self.show_present()  # the last frame shows the present, not a tick behind

    def stop_filter_thread(self, timeout: float | None = None) -> bool:
        """Show the worker's last ticks and run the filters in each tick again (the end of
        :meth:`run`, a close); with ``timeout`` [s], whether the worker ended in time."""
        s = self.session
        if getattr(s, "worker", None) is None:
            return True
        if timeout is None:
            s.settle(self.after_tick)
        return s.stop_worker(timeout)

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
        self.stop_filter_thread()
        self.session.close()
        pygame.display.quit()
