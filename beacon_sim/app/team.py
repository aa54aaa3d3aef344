"""``beacon-sim play TEAM_SCENARIO``: the window on a team of robots (issue 18).

The single-robot window (:class:`~beacon_sim.app.main.App`) around a
:class:`~beacon_sim.runs.team_live.TeamSession`, with the team's own key table
(``controls.TEAM_BINDINGS``: Tab drives the next robot), renderer and panel. Everything is
drawn with the single-robot window's pieces (``render.WorldRenderer``, ``hud.Hud``):

- every robot's true pose as the usual black outline, ringed (the ring stays visible over
  the beliefs), with its name on a tag; the driven robot on a yellow halo, its tag black;
- each team filter's belief of each robot (the marginal of its joint state): an arrow and
  the 95 % ellipse of x-y, in the team filter's colour and line style
  (``runs/styles.TEAM_STYLES``); no heading wedges (a dozen beliefs would hide the robots);
- beacon readings as the usual solid grey lines, robot-to-robot readings as dashed purple
  lines ending in a ring;
- the panel: who is driven, what each robot sees, each team filter's per-robot error and
  NEES, or the message it was switched off with.
"""

from __future__ import annotations

import math
import os
import sys
from pathlib import Path

import numpy as np
import pygame

from beacon_sim.app import palette, shapes
from beacon_sim.app.hud import Hud
from beacon_sim.app.main import App, PlayOptions, check_display, run_window
from beacon_sim.app.render import ELLIPSE_LEVEL, WorldRenderer, ipx, polyline
from beacon_sim.core.team_scenario import TeamScenario
from beacon_sim.runs.scene import NEES_BAND
from beacon_sim.runs.team_live import TeamSession, make_team_recorder

#: Estimate arrows at this fraction of the single-robot window's: a few team filters'
#: arrows on one robot leave its outline visible.
ARROW_SCALE = 0.65
#: The world legend's entries that are not team filters.
LEGEND_MARKS = ("ray", "robot_ray", "robot", "driven")


class TeamRenderer(WorldRenderer):
    """Draws a :class:`TeamSession`'s world (same signature as ``WorldRenderer.draw``, so
    the window's frame is the single-robot one)."""

    def draw(self, surf, view, session: TeamSession, colours, show, drag=None, dashes=None,
             extra=None) -> None:
        team = session.team
        self.last_world = team.world
        dashes = dashes or {}
        poses = session.poses
        radii = [r.scenario.robot_radius for r in team.robots]
        old_clip = self.begin(surf, view)
        for r, pose in zip(team.robots, poses, strict=True):
            self.sensor_discs(surf, view, r.scenario.sensors, pose)
        shown = [n for n in session.names if session.visible[n] and not session.status[n].failed]
        if show.trails:
            for trail in session.truth_trails:
                self.trail(surf, view, trail, palette.TRUTH_TRAIL, 5)
            for name in shown:
                for trail in session.trails[name]:
                    self.trail(surf, view, trail, colours[name], 2)
        for i, pose in enumerate(poses):
            self.rays(surf, view, team.world, pose, session.beacon_readings(i))
        for i, pose in enumerate(poses):
            self.robot_rays(surf, view, session, pose, session.robot_readings(i))
        self.beacons(surf, view, team.world, session.seen_ids())
        self.driven_halo(surf, view, poses[session.driven], radii[session.driven])
        for pose, radius in zip(poses, radii, strict=True):
            self.robot(surf, view, pose, radius)  # the truth UNDER every belief
        if extra is not None:
            extra(surf, view, self.lw)
        beliefs = {name: session.estimates(name) for name in shown}
        for i, radius in enumerate(radii):
            ests = [(name, est[0][i], est[1][i]) for name, est in beliefs.items() if est is not None]
            # smaller arrows than alone and no heading wedges: a dozen beliefs on three robots
            self.estimates(surf, view, ests, colours, dashes, radius, show.ellipses, ARROW_SCALE,
                           wedges=False)
        self.tags: list[pygame.Rect] = []
        for i, (r, pose) in enumerate(zip(team.robots, poses, strict=True)):
            self.robot_ring(surf, view, pose, radii[i])
            self.name_tag(surf, view, pose, radii[i], r.name, i == session.driven)
        if drag is not None:
            self._drag_ghost(surf, view, drag, session.true_pose, radii[session.driven])
        surf.set_clip(old_clip)

    def robot_rays(self, surf, view, session: TeamSession, pose, readings) -> None:
        """Robot-to-robot readings taken at ``pose``: dashed purple lines, each ending in a
        ring where the reading puts the seen robot (beacon readings are solid grey)."""
        lw = max(self.lw - 1, 3)
        for m in readings:
            idx = [session.robot_index(int(b)) for b in m.beacon_ids]
            seen_xy = np.array([session.poses[k][:2] if k is not None else pose[:2] for k in idx])
            for a, b in view.to_px(shapes.robot_rays(pose, m, seen_xy)):
                # Two robots that see each other: the two readings side by side, not on top.
                d = b - a
                n = np.array([-d[1], d[0]]) / max(float(np.hypot(*d)), 1e-9) * (lw - 1)
                a, b = a + n, b + n
                polyline(surf, palette.ROBOT_RAY, np.array([a, b]), lw, palette.ROBOT_RAY_DASH)
                pygame.draw.circle(surf, palette.ROBOT_RAY, (ipx(b[0]), ipx(b[1])), 7, 3)

    def driven_halo(self, surf, view, pose, radius: float) -> None:
        """A yellow disc with a black rim under the robot the keys drive."""
        r_px = max(radius * view.scale, 14.0) * 1.9
        c = view.to_px(np.asarray(pose[:2]))
        at = (ipx(c[0]), ipx(c[1]))
        pygame.draw.circle(surf, palette.DRIVEN, at, round(r_px))
        pygame.draw.circle(surf, palette.TEXT, at, round(r_px), 2)

    def robot_ring(self, surf, view, pose, radius: float) -> None:
        """A thin black ring around a true robot, over the beliefs: small ellipses and the
        arrows on a robot hide its outline, the ring still says where it is (and, being
        outside the chassis, covers no ellipse smaller than the robot)."""
        c = view.to_px(np.asarray(pose[:2]))
        r_px = max(radius * view.scale, 14.0) * 1.35
        pygame.draw.circle(surf, palette.ROBOT, (ipx(c[0]), ipx(c[1])), round(r_px), 2)

    def name_tag(self, surf, view, pose, radius: float, name: str, driven: bool) -> None:
        """The robot's name on a tag behind it (opposite its heading, away from the heading
        wedges and the arrows), white on black for the driven robot."""
        text = f"{name} (driven)" if driven else name
        fg, bg = (palette.BANNER_TEXT, palette.TEXT) if driven else (palette.TEXT, palette.PANEL)
        img = self.text(text, "label", fg)
        c = view.to_px(np.asarray(pose[:2]))
        r_px = max(radius * view.scale, 14.0) * (1.9 if driven else 1.3) + 6
        half = np.array(img.get_size()) / 2 + 5
        # behind the robot (screen y down), else turned by 45 degree steps: the first place
        # that covers no beacon, beacon label or other tag
        taken = [*self.beacon_rects, *getattr(self, "tags", [])]
        frame = None
        for turn in (0.0, 0.25, -0.25, 0.5, -0.5, 0.75, -0.75, 1.0):
            a = pose[2] + math.pi * (1.0 + turn)
            back = np.array([np.cos(a), -np.sin(a)])
            centre = c + back * (r_px + float(np.min(half / np.maximum(np.abs(back), 1e-9))))
            cand = img.get_rect(center=(ipx(centre[0]), ipx(centre[1]))).inflate(10, 2)
            cand.clamp_ip(surf.get_clip())  # the whole tag, its border included, stays in view
            if frame is None:
                frame = cand
            if cand.collidelist(taken) < 0:
                frame = cand
                break
        assert frame is not None
        if hasattr(self, "tags"):
            self.tags.append(frame)
        surf.fill(bg, frame)
        pygame.draw.rect(surf, palette.TEXT, frame, 2)
        surf.blit(img, img.get_rect(center=frame.center))


def short(font: pygame.font.Font, text: str, width: int) -> str:
    """``text`` cut (with a trailing '.') to fit ``width`` pixels."""
    if font.size(text)[0] <= width:
        return text
    while len(text) > 1 and font.size(text + ".")[0] > width:
        text = text[:-1]
    return text + "."


class TeamHud(Hud):
    """The team panel: time, the driven robot and its command, what each robot sees, each
    team filter's per-robot error and NEES (or why it was switched off), the legend."""

    def panel(self, surf, rect: pygame.Rect, session: TeamSession, colours, info: dict) -> None:
        x, w, y = self.begin_panel(surf, rect)
        f = self.fonts
        lh = f["hud"].get_linesize()
        sl = f["small"].get_linesize()
        y = self.title_and_clock(surf, x, w, y, session.team.name, session.time, info)
        tab = "" if getattr(session, "replaying", False) else "  (Tab)"  # Tab drives; not in a replay
        self._blit(surf, f"driving: {session.driven_name}{tab}", "hud", palette.TEXT, (x, y))
        y = self.command(surf, x, y + lh, session.next_control(), session.drive_mode) + 4
        name_w = max(f["small"].size(n)[0] for n in session.robot_names) + 12
        for i, name in enumerate(session.robot_names):
            seen = sorted(session.seen_ids(i))
            mates = session.teammates_seen(i)
            self._blit(surf, name, "small", palette.TEXT, (x, y))
            text = (f"beacons {', '.join(map(str, seen))}" if seen else "no beacon")
            r = self._blit(surf, text, "small", palette.TEXT if seen else palette.WARN,
                           (x + name_w, y))
            if mates:
                sees = "; sees " + ", ".join(mates)
                at = (r.right, y)
                if r.right + f["small"].size(sees)[0] > rect.right - 8:  # no room: next line
                    sees, at = sees[2:], (x + name_w, y + sl)
                    y += sl
                self._blit(surf, sees, "small", palette.ROBOT_RAY, at)
            y += sl
        y = self.rule(surf, rect, x, y + 4)

        # Each team filter: its label, then the error and NEES of each robot in columns.
        head_w = max(f["small"].size(t)[0] for t in ("err m", "NEES")) + 24
        col_w = max((w - head_w) // max(session.n_robots, 1), 1)
        cols = [x + head_w + k * col_w for k in range(session.n_robots)]
        for cx, name in zip(cols, session.robot_names, strict=True):
            self._blit(surf, short(f["small"], name, col_w - 6), "small", palette.TEXT_DIM, (cx, y))
        y += sl
        for k, name in enumerate(session.names):
            st = session.status[name]
            y = self.filter_label(surf, x, y, k, name, colours[name], session.visible[name])
            note = st.warning or (f"{name} switched off: {st.failed}" if st.failed else None)
            y = self.notes(surf, x, w, y, [note])
            figures = session.robot_status[name]
            if not st.failed and any(np.isfinite(r.pos_err) for r in figures):
                self._blit(surf, "err m", "small", palette.TEXT_DIM, (x + 10, y))
                for cx, rst in zip(cols, figures, strict=True):
                    self._blit(surf, f"{rst.pos_err:.2f}", "small", palette.TEXT, (cx, y))
                y += sl
                self._blit(surf, "NEES", "small", palette.TEXT_DIM, (x + 10, y))
                for cx, rst in zip(cols, figures, strict=True):
                    self.nees(surf, rst, (cx, y), label=False)
                y += sl
            y += 4

        self.footer(surf, rect, x, w, y, [
            f"ellipse: {ELLIPSE_LEVEL:.0%} of each robot's x-y; NEES band 95 %: "
            f"{NEES_BAND[0]:.2f} .. {NEES_BAND[1]:.2f}"], info)

    def legend_rows(self, width: int, names: list[str]) -> list[list[tuple[str, str]]]:
        """The legend's entries (text, what) in rows that fit ``width`` [px]: the readings
        and robots, then one entry per team filter ``names``."""
        f = self.fonts["small"]
        sample = 3 * f.get_linesize()
        items = [("beacon reading", "ray"), ("robot reading", "robot_ray"),
                 ("true robot", "robot"), ("driven (Tab)", "driven")]
        items += [(f"{name}: {ELLIPSE_LEVEL:.0%} ellipse", name) for name in names]
        room = width - 40
        rows: list[list[tuple[str, str]]] = [[]]
        used = 0
        for text, what in items:  # fill rows left to right; the filters start a new row
            wide = sample + 12 + f.size(text)[0] + 24
            if rows[-1] and (used + wide > room or (what not in LEGEND_MARKS and used
                                                    and rows[-1][-1][1] in LEGEND_MARKS)):
                rows.append([])
                used = 0
            rows[-1].append((text, what))
            used += wide
        return rows

    def legend_height(self, width: int, names: list[str]) -> int:
        """The height [px] the legend box takes under the world, margins included."""
        return len(self.legend_rows(width, names)) * (self.fonts["small"].get_linesize() + 8) + 26

    def world_legend(self, surf, area: pygame.Rect, session: TeamSession, colours, dashes,
                     lw: int) -> pygame.Rect:
        """What the lines in the world mean, with a sample of each, in a box at the top left
        of ``area`` (the strip under the world view): the readings, the robots, each team
        filter's style."""
        f = self.fonts["small"]
        sl = f.get_linesize()
        sample = 3 * sl
        rows = self.legend_rows(area.width, [n for n in session.names if session.visible[n]])
        widths = [sum(sample + 12 + f.size(t)[0] + 24 for t, _ in row) for row in rows]
        box = pygame.Rect(area.left + 8, area.top + 4, min(max(widths) + 12, area.width - 16),
                          len(rows) * (sl + 8) + 10)
        surf.fill(palette.OUTSIDE, area)  # the strip under the world, as around the world
        old_clip = surf.get_clip()
        surf.set_clip(area)
        shade = pygame.Surface(box.size, pygame.SRCALPHA)
        shade.fill((*palette.PANEL, 235))
        surf.blit(shade, box)
        pygame.draw.rect(surf, palette.PANEL_EDGE, box, 2)
        y = box.top + 8
        for row in rows:
            x = box.left + 10
            mid = y + sl // 2
            for text, what in row:
                a, b = (x, mid), (x + sample, mid)
                if what == "ray":
                    pygame.draw.line(surf, palette.RAY, a, b, 2)
                elif what == "robot_ray":
                    polyline(surf, palette.ROBOT_RAY, [a, (b[0] - 7, mid)], max(lw - 1, 3),
                             palette.ROBOT_RAY_DASH)
                    pygame.draw.circle(surf, palette.ROBOT_RAY, (b[0] - 7, mid), 7, 3)
                elif what == "robot":
                    r = pygame.Rect(0, 0, sl - 8, sl - 10)
                    r.center = (x + sample // 2, mid)
                    pygame.draw.rect(surf, palette.ROBOT, r, max(lw - 1, 2))
                    pygame.draw.circle(surf, palette.ROBOT, r.center, sl // 2 + 2, 2)
                elif what == "driven":
                    pygame.draw.circle(surf, palette.DRIVEN, (x + sample // 2, mid), sl // 2 + 2)
                    pygame.draw.circle(surf, palette.TEXT, (x + sample // 2, mid), sl // 2 + 2, 2)
                else:
                    polyline(surf, colours[what], [a, b], lw, dashes.get(what))
                x += sample + 12
                r = self._blit(surf, text, "small", palette.TEXT, (x, y))
                x = r.right + 24
            y += sl + 8
        surf.set_clip(old_clip)
        return box


class TeamApp(App):
    """The window in team mode (see the module docstring)."""

    MODE = "team"
    RENDERER = TeamRenderer
    HUD = TeamHud

    def __init__(self, session: TeamSession, size=(1280, 800), scripted: bool = False,
                 recording: Path | None = None):
        super().__init__(session, size, scripted, recording=recording)
        pygame.display.set_caption(f"beacon-sim: {session.team.name} (team)")

    def filter_styles(self, names: list[str]) -> dict[str, tuple]:
        return palette.team_filter_styles(names)

    def act(self, action: str) -> None:
        if action == "next_robot":
            self.flash(f"driving {self.session.next_robot()}")
        else:
            super().act(action)

    def world_area(self, width: int, height: int) -> tuple[int, int, int, int]:
        """The world's part of the window, less the legend's strip under it (sized for every
        filter, shown or hidden, so the world does not jump when one is hidden)."""
        x, y, w, h = super().world_area(width, height)
        return (x, y, w, h - self.hud.legend_height(w, self.session.names))

    def legend_area(self) -> pygame.Rect:
        """The strip under the world view the legend is drawn in."""
        x, y, w, h = self.view.area
        return pygame.Rect(x, y + h, w, self.hud.legend_height(w, self.session.names))

    def draw_extra(self, surf) -> None:
        self.hud.world_legend(surf, self.legend_area(), self.session, self.colours,
                              self.dashes, self.renderer.lw)

    def after_tick(self, step) -> None:
        for name, s in zip(self.session.robot_names, step.steps, strict=True):
            self.announce(s.events, who=name)

    def clear_trails(self) -> None:
        self.session.clear_trails()


def play_team(options: PlayOptions) -> int:
    """Open the window on a team session (``options.scenario`` is a TeamScenario and
    ``options.filters`` team filter names); returns the exit status. Recorded as a
    single-robot session is (``options.record``: ``recordings/<scenario>_<time>.jsonl``,
    docs/replay.md)."""
    o = options
    check_display()
    assert isinstance(o.scenario, TeamScenario)
    recorder, rec_path = (None, None)
    if o.record:
        recorder, rec_path = make_team_recorder(o.scenario, o.seed, list(o.filters), o.params)
    session = TeamSession(o.scenario, list(o.filters), o.seed, o.params, recorder)
    if o.autopilot:
        session.toggle_autopilot()
    os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
    app = TeamApp(session, o.size, scripted=o.frames is not None, recording=rec_path)
    run_window(app, o)
    if rec_path is not None:
        print(f"recorded to {rec_path}", file=sys.stderr)
    return 0


__all__ = ["TeamApp", "TeamHud", "TeamRenderer", "play_team"]
