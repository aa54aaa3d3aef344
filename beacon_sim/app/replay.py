"""``beacon-sim replay FILE`` on screen: the play window driven by a recording, with a
timeline (pause, step, speed, seek).

Each tick takes the recorded control and user commands (``user_commands.apply_commands``,
through :meth:`Session.tick`, as the recorder expects) and is checked against the recorded
short truth checksum. The recording holds poses and checksums but no random-generator
state, so a checkpoint cannot be restored: seeking backward rebuilds the simulation and the
filters and re-simulates from tick 0 (2,400 ticks take a fraction of a second), so the
picture at time t is exactly the one a straight run shows at t. Seeking forward just runs
the ticks in between.
"""

from __future__ import annotations

import os
import sys
from typing import Any

import pygame

from beacon_sim.app import palette
from beacon_sim.app.main import App
from beacon_sim.app.session import Session
from beacon_sim.core.types import Control, Step
from beacon_sim.recording import Recording
from beacon_sim.replay import replay_params, skipped_note
from beacon_sim.replay import replay_specs as _replay_specs

#: Left / Right arrows seek by this much simulated time [s].
SEEK_STEP_S = 5.0


class ReplaySession(Session):
    """A :class:`Session` whose controls and user commands come from a recording."""

    def __init__(self, recording: Recording, specs: list[str],
                 params: dict[str, dict[str, Any]] | None = None):
        self.recording = recording
        self.mismatch: str | None = None  # first tick whose truth differs from the file
        super().__init__(recording.scenario, list(specs), recording.seed, dict(params or {}))

    @property
    def total_ticks(self) -> int:
        return len(self.recording.ticks)

    @property
    def at_end(self) -> bool:
        return self.sim.tick >= self.total_ticks

    @property
    def drive_mode(self) -> str:
        name = self.recording.path.name
        return "replay " + (name if len(name) <= 28 else name[:12] + "..." + name[-13:])

    def next_control(self) -> Control:
        """The recorded control of the next tick (the last one once the recording ends)."""
        ticks = self.recording.ticks
        if not ticks:
            return Control()
        return ticks[min(self.sim.tick, len(ticks) - 1)].control

    def tick(self) -> Step:
        """The next recorded tick: its commands, its control, then the checksum check."""
        rec = self.recording.ticks[self.sim.tick]
        self.pending = [dict(c) for c in rec.commands]
        for c in self.pending:  # recorded show / hide of a filter (display only)
            if c["kind"] == "toggle" and c.get("filter") in self.visible:
                self.visible[c["filter"]] = not self.visible[c["filter"]]
        step = super().tick()
        if (self.mismatch is None and rec.short_checksum is not None
                and self.sim.truth_checksum[:8] != rec.short_checksum):
            self.mismatch = (f"{self.recording.path}:{rec.line}: replay differs from the recording "
                             f"at tick {rec.tick} (t = {self.sim.time:g} s)")
        return step

    def checksum_status(self) -> str:
        """"verified", "MISMATCH ...", or how far the check went."""
        if self.mismatch:
            return f"MISMATCH: {self.mismatch}"
        end = self.recording.end
        if self.at_end and end is not None:
            return "verified" if end["checksum"] == self.sim.truth_checksum else \
                "MISMATCH with the end line's checksum"
        return f"checked tick by tick up to tick {self.sim.tick}"


class ReplayApp(App):
    """The window in replay mode: no driving, a timeline at the bottom of the world view."""

    MODE = "replay"

    def __init__(self, recording: Recording, specs: list[str],
                 params: dict[str, dict[str, Any]] | None = None, size=(1280, 800),
                 scripted: bool = False):
        self.replay_of = recording
        self.specs = list(specs)
        self.params = dict(params or {})
        self.reported = False
        self._open(ReplaySession(recording, specs, params), size, scripted)

    def _open(self, session, size, scripted: bool) -> None:
        """The timeline's own state, then the window around ``session`` (also for the
        MRCLAM window, which plays something other than a recording)."""
        self.user_flips: set[str] = set()  # filters the user showed / hid (kept over seeks)
        self.seek_to: int | None = None
        self.scrubbing = False
        App.__init__(self, session, size, scripted)

    # --- layout ---------------------------------------------------------------------------
    def world_area(self, width: int, height: int) -> tuple[int, int, int, int]:
        th = self.fonts["hud"].get_linesize() + 30
        self.timeline_rect = pygame.Rect(0, height - th, width, th)
        return (0, 0, width, height - th)

    def _bar_rect(self) -> pygame.Rect:
        """The seekable bar inside the timeline strip (right of the time text)."""
        r = self.timeline_rect
        text_w = self.fonts["hud"].size("0000.0 / 0000.0 s")[0] + 30
        return pygame.Rect(r.left + text_w, r.top + 12, max(r.width - text_w - 24, 40), r.height - 24)

    def tick_at(self, x_px: float) -> int:
        """The tick under a horizontal pixel position of the bar (clamped)."""
        bar = self._bar_rect()
        frac = min(max((x_px - bar.left) / bar.width, 0.0), 1.0)
        return round(frac * self.session.total_ticks)

    # --- seeking --------------------------------------------------------------------------
    def seek(self, tick: int) -> None:
        """Show the run at ``tick``: forward by running the ticks in between, backward by
        rebuilding everything and re-simulating from the start."""
        s = self.session
        tick = min(max(int(tick), 0), s.total_ticks)
        if tick < s.sim.tick:
            s.close()
            s = self.session = ReplaySession(self.replay_of, self.specs, self.params)
            for name in self.user_flips:
                if name in s.visible:
                    s.visible[name] = not s.visible[name]
        while s.sim.tick < tick:
            s.tick()
        self.clock.accumulator = 0.0

    def ticks_due(self, real_dt: float) -> int:
        if self.seek_to is not None:  # at most one seek per frame (a drag sends many)
            target, self.seek_to = self.seek_to, None
            self.seek(target)
        n = min(super().ticks_due(real_dt), self.session.total_ticks - self.session.sim.tick)
        return max(n, 0)

    def frame(self, real_dt: float) -> None:
        super().frame(real_dt)
        s = self.session
        if not self.reported and (s.at_end or s.mismatch):
            self.reported = True
            status = s.checksum_status()
            self.flash(("end of the recording: truth checksum " + status) if not s.mismatch
                       else status)
            print(f"replay {self.replay_of.path}: tick {s.sim.tick} of {s.total_ticks}, truth "
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

    def act(self, action: str) -> None:
        s = self.session
        step = round(SEEK_STEP_S / s.scenario.dt)
        if action == "seek_back":
            self.seek_to = max((self.seek_to if self.seek_to is not None else s.sim.tick) - step, 0)
        elif action == "seek_forward":
            self.seek_to = (self.seek_to if self.seek_to is not None else s.sim.tick) + step
        elif action == "seek_start":
            self.seek_to = 0
        elif action.startswith("toggle"):
            i = int(action[len("toggle"):]) - 1
            if i < len(s.names):
                name = s.names[i]
                s.visible[name] = not s.visible[name]
                self.user_flips ^= {name}
        else:
            super().act(action)

    # --- drawing --------------------------------------------------------------------------
    def marks(self) -> list[tuple[int, tuple[int, int, int]]]:
        """(tick, colour) marks on the timeline: the recorded user commands (kidnaps in the
        warning colour, resets and toggles dim)."""
        return [(rec.tick, palette.WARN if rec.commands[0]["kind"] == "kidnap" else palette.TEXT_DIM)
                for rec in self.replay_of.ticks if rec.commands]

    def draw_extra(self, surf) -> None:
        """The timeline: elapsed / total, the bar with the recorded commands marked, the
        position marker."""
        s = self.session
        r = self.timeline_rect
        surf.fill(palette.PANEL, r)
        pygame.draw.line(surf, palette.PANEL_EDGE, r.topleft, r.topright, 3)
        dt = s.scenario.dt
        text = f"{s.sim.tick * dt:6.1f} / {s.total_ticks * dt:.1f} s"
        img = self.fonts["hud"].render(text, True, palette.TEXT)
        surf.blit(img, img.get_rect(midleft=(r.left + 14, r.centery)))
        bar = self._bar_rect()
        total = max(s.total_ticks, 1)
        pygame.draw.rect(surf, palette.GRID_MINOR, bar, border_radius=6)
        done = bar.copy()
        done.width = round(bar.width * min(s.sim.tick / total, 1.0))
        if done.width > 0:
            pygame.draw.rect(surf, palette.SENSOR_EDGE, done, border_radius=6)
        for tick, colour in self.marks():
            x = bar.left + round(bar.width * tick / total)
            pygame.draw.line(surf, colour, (x, bar.top + 2), (x, bar.bottom - 3), 3)
        pygame.draw.rect(surf, palette.PANEL_EDGE, bar, 2, border_radius=6)
        x = bar.left + round(bar.width * min(s.sim.tick / total, 1.0))
        pygame.draw.line(surf, palette.TEXT, (x, r.top + 5), (x, r.bottom - 5), 5)
        pygame.draw.circle(surf, palette.TEXT, (x, bar.centery), 9)
        if self.clock.paused or s.at_end:
            label = "END" if s.at_end else "PAUSED"
            tag = self.fonts["small"].render(label, True, palette.BANNER_TEXT)
            box = tag.get_rect(bottomright=(bar.right - 6, bar.top - 4)).inflate(10, 2)
            if box.top > self.view.area[1]:
                pygame.draw.rect(surf, palette.WARN, box, border_radius=4)
                surf.blit(tag, tag.get_rect(center=box.center))


def replay_specs(recording: Recording, requested: list[str] | None) -> tuple[list[str], list[str]]:
    """(filters to run, recorded filters skipped): ``--filter`` wins; otherwise the recorded
    built-in ones (a recording never makes beacon-sim import a file or module it names)."""
    return _replay_specs(recording, requested or None)


def show_replay(recording: Recording, args) -> int:
    """``beacon-sim replay FILE`` without ``--headless``: the window, until quit (or
    ``--frames N``, each frame counting 1/60 s). Exit status 2 when the truth differs."""
    from beacon_sim.cli import UsageError, _filter_params

    frames = getattr(args, "frames", None)
    if frames is not None and frames < 1:
        raise UsageError(f"--frames {frames}: expected a positive number of frames")
    specs, skipped = replay_specs(recording, getattr(args, "filters", None))
    for spec in skipped:
        print(skipped_note(spec), file=sys.stderr)
    params = replay_params(recording, _filter_params(args))
    os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
    app = ReplayApp(recording, specs, params, scripted=frames is not None)
    try:
        app.run(frames)
        if getattr(args, "screenshot", None):
            app.save_screenshot(args.screenshot)
        s = app.session
        if not app.reported:
            print(f"replay {recording.path}: stopped at tick {s.sim.tick} of {s.total_ticks}, "
                  f"truth checksum {s.checksum_status()}", file=sys.stderr)
        return 2 if s.mismatch else 0
    finally:
        app.close()


__all__ = ["ReplayApp", "ReplaySession", "replay_specs", "show_replay"]
