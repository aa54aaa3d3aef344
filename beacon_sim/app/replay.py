"""``beacon-sim replay FILE`` on screen: the play window driven by a recording, with a
timeline (pause, step, speed, seek).

Each tick takes the recorded control and user commands (``user_commands.apply_commands``,
through :meth:`Session.tick`, as the recorder expects) and is checked against the recorded
short truth checksum. The recording holds poses and checksums but no random-generator
state, so a checkpoint cannot be restored: seeking backward rebuilds the simulation and the
filters and re-simulates from tick 0 (2,400 ticks take a fraction of a second), so the
picture at time t is exactly the one a straight run shows at t. Seeking forward just runs
the ticks in between.

A team's recording opens the same window in its team view (``App.team_view``), with this
timeline, driven by the same :class:`~beacon_sim.runs.replay.ReplaySession` over its robots.
"""

from __future__ import annotations

import os
import sys
from typing import Any, cast

import pygame

from beacon_sim.app import palette
from beacon_sim.app.estimate_layer import ELLIPSE_SCALE2
from beacon_sim.app.strokes import polyline
from beacon_sim.app.text import wrap_text
from beacon_sim.app.window import App
from beacon_sim.core.geometry import covariance_ellipse
from beacon_sim.io.recording import Recording
from beacon_sim.runs.live import Session
from beacon_sim.runs.mrclam import MrclamPlayback
from beacon_sim.runs.replay import ReplaySession
from beacon_sim.runs.scene import Timeline
from beacon_sim.runs.smoothing import SmoothedTrack

#: Left / Right arrows seek by this much simulated time [s].
SEEK_STEP_S = 5.0
#: The smoothed ellipse's dashes [px on, px off].
SMOOTHED_DASH = (10, 6)


def tint(colour: tuple[int, int, int], amount: float = 0.45) -> tuple[int, int, int]:
    """``colour`` mixed with white by ``amount`` (0: itself, 1: white)."""
    return tuple(round(c + (255 - c) * amount) for c in colour)  # type: ignore[return-value]


class ReplayApp(App):
    """The window in replay mode: no driving, a timeline at the bottom of the world view.

    ``session`` is a :class:`~beacon_sim.runs.replay.ReplaySession` or any scene with the same
    timeline methods (``total_ticks``, ``at_end``, ``seek``, ``tick``, ``marks``), such as a
    finished MRCLAM run (:class:`~beacon_sim.runs.mrclam.MrclamPlayback`).
    """

    MODE = "replay"

    def __init__(self, session: ReplaySession | MrclamPlayback, size=(1280, 800),
                 scripted: bool = False, smoothed: dict[str, SmoothedTrack] | None = None):
        self.reported = False
        self.smoothed = smoothed or {}  # --smooth: each smoothed filter's whole run
        if self.smoothed:
            self.world_overlay = self.draw_smoothed
        self.end_tick: int | None = None  # stop the window here (--end, --gif)
        self.stop_at_end = False  # quit once the recording is over (--gif)
        self.user_flips: set[str] = set()  # filters the user showed / hid (kept over seeks)
        self.seek_to: int | None = None
        self.scrubbing = False
        self.timeline: Timeline = session
        super().__init__(cast("Session", session), size, scripted)

    # --- layout ---------------------------------------------------------------------------
    def world_area(self, width: int, height: int) -> tuple[int, int, int, int]:
        th = self.fonts["hud"].get_linesize() + 30
        self.timeline_rect = pygame.Rect(0, height - th, width, th)
        return super().world_area(width, height - th)  # the team window's legend strip too

    def _bar_rect(self) -> pygame.Rect:
        """The seekable bar inside the timeline strip (right of the time text)."""
        r = self.timeline_rect
        text_w = self.fonts["hud"].size("0000.0 / 0000.0 s")[0] + 30
        return pygame.Rect(r.left + text_w, r.top + 12, max(r.width - text_w - 24, 40), r.height - 24)

    def tick_at(self, x_px: float) -> int:
        """The tick under a horizontal pixel position of the bar (clamped)."""
        bar = self._bar_rect()
        frac = min(max((x_px - bar.left) / bar.width, 0.0), 1.0)
        return round(frac * self.timeline.total_ticks)

    # --- seeking --------------------------------------------------------------------------
    def seek(self, tick: int) -> None:
        """Show the run at ``tick`` (the scene knows how: see its ``seek``). A banner of an
        event (a bump, a kidnap) belongs to the time it happened: a seek clears it."""
        self.timeline.seek(tick, self.user_flips)
        self.clock.accumulator = 0.0
        self.banner_until = -1.0

    def ticks_due(self, real_dt: float) -> int:
        if self.seek_to is not None:  # at most one seek per frame (a drag sends many)
            target, self.seek_to = self.seek_to, None
            self.seek(target)
        n = min(super().ticks_due(real_dt), self.timeline.total_ticks - self.session.tick_count)
        return self.ticks_due_capped(max(n, 0))

    def ticks_due_capped(self, n: int) -> int:
        """At most the ticks left before ``end_tick``."""
        if self.end_tick is None:
            return n
        return max(min(n, self.end_tick - self.session.tick_count), 0)

    def frame(self, real_dt: float) -> None:
        super().frame(real_dt)
        s = self.session
        if (self.end_tick is not None and s.tick_count >= self.end_tick) or (
                self.stop_at_end and self.timeline.at_end):
            self.running = False
        if not self.reported and isinstance(s, ReplaySession) \
                and (self.timeline.at_end or s.mismatch):
            self.reported = True
            status = s.checksum_status()
            self.flash(("end of the recording: truth checksum " + status) if not s.mismatch
                       else status)
            print(f"replay {s.recording.path}: tick {s.tick_count} of {self.timeline.total_ticks}, truth "
                  f"checksum {status}", file=sys.stderr)

    # --- events ---------------------------------------------------------------------------
    def handle(self, event) -> None:
        if event.type == pygame.MOUSEBUTTONDOWN and event.button == 1:
            if self.timeline_rect.collidepoint(event.pos):
                self.scrubbing = True
                self.seek_to = self.tick_at(event.pos[0])
            return
        if event.type == pygame.MOUSEMOTION and self.scrubbing:
            self.seek_to = self.tick_at(event.pos[0])
            return
        if event.type == pygame.MOUSEBUTTONUP and event.button == 1:
            self.scrubbing = False
            return
        super().handle(event)

    # --- the timeline's actions (controls.REPLAY_BINDINGS; App.act dispatches) -------------
    def _seek_step(self) -> int:
        return round(SEEK_STEP_S / self.session.scenario.dt)

    def _seek_from(self) -> int:
        return self.seek_to if self.seek_to is not None else self.session.tick_count

    def act_seek_back(self) -> None:
        self.seek_to = max(self._seek_from() - self._seek_step(), 0)

    def act_seek_forward(self) -> None:
        self.seek_to = self._seek_from() + self._seek_step()

    def act_seek_start(self) -> None:
        self.seek_to = 0

    def act_toggle(self, number: int) -> None:
        """Show / hide filter ``number`` at once (display only; kept over seeks)."""
        s = self.session
        if number - 1 < len(s.names):
            name = s.names[number - 1]
            s.visible[name] = not s.visible[name]
            self.user_flips ^= {name}

    # --- drawing --------------------------------------------------------------------------
    def marks(self) -> list[tuple[int, tuple[int, int, int]]]:
        """(tick, colour) marks on the timeline: the recorded user commands (kidnaps in the
        warning colour, resets and toggles dim)."""
        return [(tick, palette.WARN if kind == "kidnap" else palette.TEXT_DIM)
                for tick, kind in self.timeline.marks()]

    def draw_mismatch(self, surf) -> None:
        """While a replay differs from its recording: a banner across the bottom of the world
        view, for as long as the window shows the replay (what differs, where, and that the
        run is not verified). A recording made before beacon-sim's portable maths whose truth
        differs gets a banner saying so (not verified, not an edit)."""
        why = getattr(self.session, "mismatch", None)
        heading = "NOT VERIFIED: the replay differs from the recording"
        if not why:
            why = getattr(self.session, "unverified", None)
            heading = "NOT VERIFIED: an older recording"
            why = why and why.removeprefix("not verified: ")
        if not why:
            return
        x, y, w, h = self.view.area
        font = self.fonts["hud"]
        title = self.fonts["banner"].render(heading, True, palette.BANNER_TEXT)
        lines = wrap_text(font, why, w - 60)[:4]
        imgs = [font.render(line, True, palette.BANNER_TEXT) for line in lines]
        lh = font.get_linesize()
        box = pygame.Rect(0, 0, min(w - 20, max([title.get_width(), *(i.get_width() for i in imgs)]) + 36),
                          title.get_height() + lh * len(imgs) + 22)
        box.midbottom = (x + w // 2, y + h - 10)
        pygame.draw.rect(surf, palette.BANNER_BG, box, border_radius=10)
        pygame.draw.rect(surf, palette.TEXT, box, 3, border_radius=10)
        surf.blit(title, title.get_rect(midtop=(box.centerx, box.top + 8)))
        for k, img in enumerate(imgs):
            surf.blit(img, img.get_rect(midtop=(box.centerx, box.top + 12 + title.get_height() + k * lh)))

    def draw_smoothed(self, surf, view, lw: int) -> None:
        """``--smooth`` (the world overlay, under the estimates): each visible smoothed
        filter's smoothed trajectory up to the current tick and its dashed 95 % ellipse there,
        in a light tint of the filter's colour beside the filter's own (the smoother has used
        every reading of the run, later ones too)."""
        s = self.session
        tick = s.tick_count
        lw = max(2 * lw // 3, 2)
        for name, tr in self.smoothed.items():
            k = tr.at(tick)
            if k is None or not s.visible.get(name, False):
                continue
            colour = tint(self.colours[name])
            if k >= 1 and self.show.trails:
                polyline(surf, colour, view.to_px(tr.smoothed_means[:k + 1, :2]), lw)
            if self.show.ellipses:
                ellipse = covariance_ellipse(tr.smoothed_means[k, :2], tr.smoothed_covs[k, :2, :2],
                                             ELLIPSE_SCALE2, 96)
                polyline(surf, colour, view.to_px(ellipse), lw, dash=SMOOTHED_DASH, closed=True)

    def draw_smoothed_legend(self, surf) -> None:
        """What the light lines are, bottom left of the world view."""
        font = self.fonts["small"]
        img = font.render("light line, dashed ellipse: smoothed (RTS: every reading of the run, later "
                          "ones too)", True, palette.TEXT)
        x, y, _, h = self.view.area
        box = img.get_rect(bottomleft=(x + 14, y + h - 12)).inflate(12, 6)
        pygame.draw.rect(surf, palette.PANEL, box, border_radius=4)
        pygame.draw.rect(surf, palette.PANEL_EDGE, box, 1, border_radius=4)
        surf.blit(img, img.get_rect(center=box.center))

    def draw_extra(self, surf) -> None:
        """The timeline: elapsed / total, the bar with the recorded commands marked, the
        position marker; the mismatch banner when the replay differs (and a team's legend);
        the smoothed tracks (``--smooth``)."""
        super().draw_extra(surf)
        if self.smoothed:
            self.draw_smoothed_legend(surf)
        self.draw_mismatch(surf)
        s = self.session
        r = self.timeline_rect
        surf.fill(palette.PANEL, r)
        pygame.draw.line(surf, palette.PANEL_EDGE, r.topleft, r.topright, 3)
        dt = s.scenario.dt
        text = f"{s.tick_count * dt:6.1f} / {self.timeline.total_ticks * dt:.1f} s"
        img = self.fonts["hud"].render(text, True, palette.TEXT)
        surf.blit(img, img.get_rect(midleft=(r.left + 14, r.centery)))
        bar = self._bar_rect()
        total = max(self.timeline.total_ticks, 1)
        pygame.draw.rect(surf, palette.GRID_MINOR, bar, border_radius=6)
        done = bar.copy()
        done.width = round(bar.width * min(s.tick_count / total, 1.0))
        if done.width > 0:
            pygame.draw.rect(surf, palette.SENSOR_EDGE, done, border_radius=6)
        for tick, colour in self.marks():
            x = bar.left + round(bar.width * tick / total)
            pygame.draw.line(surf, colour, (x, bar.top + 2), (x, bar.bottom - 3), 3)
        pygame.draw.rect(surf, palette.PANEL_EDGE, bar, 2, border_radius=6)
        x = bar.left + round(bar.width * min(s.tick_count / total, 1.0))
        pygame.draw.line(surf, palette.TEXT, (x, r.top + 5), (x, r.bottom - 5), 5)
        pygame.draw.circle(surf, palette.TEXT, (x, bar.centery), 9)
        if self.clock.paused or self.timeline.at_end:
            label = "END" if self.timeline.at_end else "PAUSED"
            tag = self.fonts["small"].render(label, True, palette.BANNER_TEXT)
            box = tag.get_rect(bottomright=(bar.right - 6, bar.top - 4)).inflate(10, 2)
            if box.top > self.view.area[1]:
                pygame.draw.rect(surf, palette.WARN, box, border_radius=4)
                surf.blit(tag, tag.get_rect(center=box.center))


def show_replay(recording: Recording, specs: list[str], params: dict[str, dict[str, Any]],
                frames: int | None = None, screenshot: str | None = None, *,
                paused: bool = False, gif: str | None = None, start: float | None = None,
                end: float | None = None, size: tuple[int, int] = (1280, 800),
                gif_width: int | None = 640, foxglove: int | None = None,
                smoothed: dict[str, SmoothedTrack] | None = None) -> int:
    """The replay window until quit (or ``frames`` frames, each counting 1/60 s); saves the
    last frame to ``screenshot``. Returns 2 when the replay differs from the recording (0
    for a recording made before the portable maths whose truth differs: not verified, said
    on the banner and stderr).

    ``start`` / ``end`` [s]: seek to ``start`` first, stop at ``end``. With ``gif`` the
    window is scripted (1/60 s per frame, as fast as it draws), captures every 6th frame
    from ``start`` to ``end`` (default: the end of the recording) and writes the GIF."""
    from beacon_sim.app.display import check_display
    from beacon_sim.app.main import finish_gif
    from beacon_sim.app.main import start as start_app

    check_display()  # no window to show it in: one line, exit 2 (not an invisible replay)
    os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
    session = ReplaySession(recording, specs, params)
    app = ReplayApp(session, size, scripted=frames is not None or gif is not None, smoothed=smoothed)
    dt = session.scenario.dt
    if start:
        app.seek(min(round(start / dt), session.total_ticks))
    if end is not None:
        app.end_tick = min(round(end / dt), session.total_ticks)
    app.stop_at_end = gif is not None
    start_app(app, paused=paused and gif is None, gif=gif, gif_width=gif_width)
    from beacon_sim.app.foxglove import stream

    live = stream(session, foxglove)  # --foxglove PORT: streamed live too (not a team replay)
    try:
        app.run(frames)
        if screenshot:
            app.save_screenshot(screenshot)
        finish_gif(app)
        s = app.session
        assert isinstance(s, ReplaySession)
        if not app.reported:
            print(f"replay {recording.path}: stopped at tick {s.tick_count} of {s.total_ticks}, "
                  f"truth checksum {s.checksum_status()}", file=sys.stderr)
        return 2 if s.mismatch else 0
    finally:
        app.close()
        if live is not None:
            live.close()


__all__ = ["ReplayApp", "show_replay"]
