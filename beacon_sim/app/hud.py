"""The side panel (time, command, beacons in view, per-filter errors and NEES, legend),
the kidnap banner and the help overlay (generated from ``controls.BINDINGS``)."""

from __future__ import annotations

import math

import numpy as np
import pygame

from beacon_sim.app import association_layer, controls, palette
from beacon_sim.app.render import ELLIPSE_LEVEL, ELLIPSE_SCALE2, missed_ids, polyline, sensors_read
from beacon_sim.core import sensor_kinds
from beacon_sim.core.clutter import UNKNOWN_ID
from beacon_sim.core.sensor_kinds import is_scan, scan_sensors
from beacon_sim.runs.scene import NEES_WINDOW_BAND, NEES_WINDOW_S, Scene


def wrap_text(font: pygame.font.Font, text: str, width: int) -> list[str]:
    """Greedy word wrap to ``width`` pixels."""
    lines: list[str] = []
    line = ""
    for word in text.split():
        trial = f"{line} {word}".strip()
        if line and font.size(trial)[0] > width:
            lines.append(line)
            line = word
        else:
            line = trial
    if line:
        lines.append(line)
    return lines


#: The panel says the delivered speed when it is below this fraction of the asked one.
SHORT_OF_SPEED = 0.9


def fit_text(font: pygame.font.Font, text: str, width: int) -> str:
    """``text``, or its middle cut out (``assignment_kf_2026...1733.jsonl``) to fit ``width``
    pixels: both ends stay readable."""
    if font.size(text)[0] <= width:
        return text
    keep = len(text)
    while keep > 2:
        keep -= 1
        head, tail = text[: (keep + 1) // 2], text[len(text) - keep // 2:]
        cut = f"{head}...{tail}"
        if font.size(cut)[0] <= width:
            return cut
    return text[:1] + "..."


#: The world legend's entries that are not filters (a team's legend strip).
LEGEND_MARKS = ("ray", "robot_ray", "robot", "driven")


def short(font: pygame.font.Font, text: str, width: int) -> str:
    """``text`` cut (with a trailing '.') to fit ``width`` pixels."""
    if font.size(text)[0] <= width:
        return text
    while len(text) > 1 and font.size(text + ".")[0] > width:
        text = text[:-1]
    return text + "."


class Hud:
    """Draws the panel, banner and help; remembers the help lines it drew (for tests)."""

    def __init__(self, fonts: dict[str, pygame.font.Font], mode: str = "play"):
        self.fonts = fonts
        self.mode = mode
        self.help_drawn: list[tuple[str, str]] = []
        self._cache: dict[tuple, pygame.Surface] = {}
        self._legend: tuple[tuple, pygame.Surface, pygame.Rect] | None = None  # world_legend's picture

    def _text(self, text: str, font: str, colour) -> pygame.Surface:
        """The rendered text, from a cache (most of the panel is the same every frame)."""
        key = (text, font, colour)
        img = self._cache.get(key)
        if img is None:
            if len(self._cache) > 400:
                self._cache.clear()
            img = self._cache[key] = self.fonts[font].render(text, True, colour)
        return img

    def _blit(self, surf, text: str, font: str, colour, at, bg=None) -> pygame.Rect:
        img = self._text(text, font, colour)
        r = img.get_rect(topleft=(int(at[0]), int(at[1])))
        if bg is not None:
            surf.fill(bg, r.inflate(8, 2))
        surf.blit(img, r)
        return r

    def panel(self, surf, rect: pygame.Rect, session: Scene, colours, info: dict) -> None:
        """The side panel. ``info``: speed, paused, fps, recording (path or None), message.
        A team's panel is :meth:`team_panel`."""
        if getattr(session, "n_robots", 1) > 1:
            self.team_panel(surf, rect, session, colours, info)
            return
        x, w, y = self.begin_panel(surf, rect)
        f = self.fonts
        lh = f["hud"].get_linesize()
        sl = f["small"].get_linesize()
        y = self.title_and_clock(surf, x, w, y, session.scenario.name, session.time, info)
        y = self.command(surf, x, y, session.next_control(), session.drive_mode)
        world = session.scenario.world
        scanning = bool(scan_sensors(session.scenario.sensors))
        if scanning:  # a map world: what the range finder senses
            beams, hits = scan_in_view(session)
            text = f"scan: {hits} of {beams} beams hit" if beams else "scan: none yet"
            self._blit(surf, text, "hud", palette.WARN if beams and not hits else palette.TEXT,
                       (x, y))
            y += lh
        if world.beacons or not scanning:
            labelled, unlabelled, seen = beacons_in_view(session)
            self._blit(surf, f"beacons in view: {len(seen)}", "hud",
                       palette.WARN if not seen else palette.TEXT, (x, y))
            y += lh
            missed = sorted(missed_ids(sensors_read(session.scenario, session.tick_count),
                                       world, session.true_pose, seen))
            indent = f["small"].size("  ")[0]
            for line in wrap_text(f["small"], ids_text(labelled, unlabelled), w - indent):
                self._blit(surf, "  " + line, "small", palette.TEXT_DIM, (x, y))
                y += sl
            if missed:  # in the drawn sensor disc but not detected: ringed dashed on the map
                # wrapped to the panel's width: a data set misses a dozen landmarks at once
                for line in wrap_text(f["small"], f"missed in range: {', '.join(map(str, missed))}",
                                      w - indent):
                    self._blit(surf, "  " + line, "small", palette.WARN, (x, y))
                    y += sl
        for text in kind_lines(session):   # kinds registered beside the built-in ones
            self._blit(surf, text, "small", palette.TEXT, (x, y))
            y += sl
        y += 6
        y = self.rule(surf, rect, x, y)

        for i, name in enumerate(session.names):
            st = session.status[name]
            y = self.filter_label(surf, x, y, i, name, colours[name], session.visible[name])
            note = st.warning or (f"{name} switched off: {st.failed}" if st.failed else None)
            y = self.notes(surf, x, w, y, [note, info.get("reload_errors", {}).get(name)])
            if st.failed:
                y += 4
                continue
            if math.isfinite(st.pos_err):
                deg = math.degrees(st.heading_err)
                r = self._blit(surf, f"err {st.pos_err:5.2f} m {deg:+6.1f} deg", "small",
                               palette.TEXT, (x + 10, y))
                nx = max(x + int(w * 0.66), r.right + sl // 2)
                if nx + f["small"].size(nees_label(st))[0] + 8 > rect.right - 6:  # no room:
                    y += sl  # its own line
                    nx = x + 10
                self.nees(surf, st, (nx, y))
                y += sl
                if math.isfinite(st.pos_sigma):
                    sig = f"sigma {st.pos_sigma:5.2f} m {math.degrees(st.heading_sigma):6.1f} deg"
                    self._blit(surf, sig, "small", palette.TEXT_DIM, (x + 10, y))
                    y += f["small"].get_linesize()
            y += 4

        if info.get("bound") is not None:
            bpos, bhead = info["bound"]
            self._blit(surf, "best possible (PCRB, B)", "small", palette.TEXT, (x, y))
            y += f["small"].get_linesize()
            size = f"{bpos:5.2f} m" if bpos >= 0.01 else f"{bpos * 1000:4.1f} mm"  # map worlds: mm
            self._blit(surf, f"sigma {size} {math.degrees(bhead):6.1f} deg", "small",
                       palette.TEXT_DIM, (x + 10, y))
            y += f["small"].get_linesize()
            for name in inside_the_bound(session, bpos):
                for line in wrap_text(f["small"], f"{name} claims more than is possible", w - 10):
                    self._blit(surf, line, "small", palette.WARN, (x + 10, y))
                    y += f["small"].get_linesize()
            y += 4

        self.footer(surf, rect, x, w, y, [
            f"ellipse: {ELLIPSE_LEVEL:.0%} of x-y (chi2 = {ELLIPSE_SCALE2:.2f})",
            "wedge: heading +-2 sigma",
            *nees_legend(),
            "black outline: true robot; line: path",
        ], info)

    # --- the panel's pieces (the single-robot and the team panel) -------------------------
    def team_panel(self, surf, rect: pygame.Rect, session, colours, info: dict) -> None:
        """The panel of a team: time, the driven robot and its command, what each robot
        sees, each filter's per-robot error and NEES (or why it was switched off)."""
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
            ids = session.seen_ids(i)
            seen = sorted(ids - {UNKNOWN_ID})
            mates = session.teammates_seen(i)
            self._blit(surf, name, "small", palette.TEXT, (x, y))
            text = "; ".join([f"beacons {', '.join(map(str, seen))}"] * bool(seen)
                             + ["beacons without IDs"] * (UNKNOWN_ID in ids)) or "no beacon"
            r = self._blit(surf, text, "small", palette.TEXT if ids else palette.WARN,
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
            f"ellipse: {ELLIPSE_LEVEL:.0%} of each robot's x-y", *nees_legend()], info)

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

    def world_legend(self, surf, area: pygame.Rect, session, colours, dashes,
                     lw: int) -> pygame.Rect:
        """What the lines in the world mean, with a sample of each, in a box at the top left
        of ``area`` (the strip under the world view): the readings, the robots, each team
        filter's style. Drawn once into a picture kept until what it shows changes (the
        filters shown, their styles, the size), then blitted: the same pixels every frame."""
        names = [n for n in session.names if session.visible[n]]
        key = (area.size, lw, tuple((n, colours[n], tuple(dashes.get(n) or ())) for n in names))
        if self._legend is None or self._legend[0] != key:
            pic = pygame.Surface(area.size, 0, surf)
            box = self._draw_world_legend(pic, pic.get_rect(), names, colours, dashes, lw)
            self._legend = (key, pic, box)
        _, pic, box = self._legend
        surf.blit(pic, area)
        return box.move(area.topleft)

    def _draw_world_legend(self, surf, area: pygame.Rect, names: list[str], colours, dashes,
                           lw: int) -> pygame.Rect:
        """:meth:`world_legend`'s drawing, of the filters ``names``, onto ``surf``."""
        f = self.fonts["small"]
        sl = f.get_linesize()
        sample = 3 * sl
        rows = self.legend_rows(area.width, names)
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

    def begin_panel(self, surf, rect: pygame.Rect) -> tuple[int, int, int]:
        """The panel's background and left edge; returns (x, text width, y) [px]."""
        surf.fill(palette.PANEL, rect)
        pygame.draw.line(surf, palette.PANEL_EDGE, rect.topleft, rect.bottomleft, 3)
        self.text_right = rect.right - 10  # where a panel line must end [px]
        return rect.left + 16, rect.width - 28, rect.top + 10

    def title_and_clock(self, surf, x: int, w: int, y: int, title: str, t: float,
                        info: dict) -> int:
        """The scenario's name, then the time, the speed factor and PAUSED / running."""
        lh = self.fonts["hud"].get_linesize()
        # a long name (a data set's run) in the smaller font, and cut only if still too long
        font = "title" if self.fonts["title"].size(title)[0] <= w else "hud"
        self._blit(surf, short(self.fonts[font], title, w), font, palette.TEXT, (x, y))
        y += self.fonts["title"].get_linesize() + 2
        state = "PAUSED" if info.get("paused") else "running"
        speed = info.get("speed", 1.0)
        r = self._blit(surf, f"t = {t:7.2f} s", "hud", palette.TEXT, (x, y))
        self._blit(surf, f"x{speed:g}  {state}", "hud",
                   palette.WARN if info.get("paused") else palette.TEXT,
                   (max(x + int(w * 0.55), r.right + lh // 2), y))
        y += lh
        got = info.get("delivered")
        if got is not None and not info.get("paused") and got < SHORT_OF_SPEED * speed:
            # the machine cannot keep up: say what the class actually sees
            self._blit(surf, f"delivering only x{got:.2g} (busy)", "small", palette.WARN, (x, y))
            y += self.fonts["small"].get_linesize()
        return y

    def command(self, surf, x: int, y: int, c, mode: str) -> int:
        """The command in force (v, omega) and who drives."""
        lh = self.fonts["hud"].get_linesize()
        self._blit(surf, f"v = {c.v:+.2f} m/s", "hud", palette.TEXT, (x, y))
        y += lh
        self._blit(surf, f"omega = {c.omega:+.2f} rad/s", "hud", palette.TEXT, (x, y))
        y += lh
        self._blit(surf, mode, "small", palette.TEXT_DIM, (x, y))
        return y + self.fonts["small"].get_linesize()

    def rule(self, surf, rect: pygame.Rect, x: int, y: int) -> int:
        """A horizontal separator across the panel."""
        pygame.draw.line(surf, palette.GRID_MAJOR, (x, y), (rect.right - 12, y), 2)
        return y + 8

    def filter_label(self, surf, x: int, y: int, i: int, name: str, colour, visible: bool) -> int:
        """A filter's swatch (filled when shown), its number (the 1-9 key) and name."""
        lh = self.fonts["hud"].get_linesize()
        sw = pygame.Rect(x, y + 4, round(lh * 0.65), lh - 8)
        if visible:
            surf.fill(colour, sw)
        pygame.draw.rect(surf, colour, sw, 3)
        room = getattr(self, "text_right", 10**6) - (sw.right + lh // 4)
        font = self.fonts["hud"]
        label = f"{i + 1}  {name}"
        if not visible:  # "(hidden)", or the shorter "(off)" where that does not fit
            label += "  (hidden)" if font.size(label + "  (hidden)")[0] <= room else "  (off)"
        self._blit(surf, fit_text(font, label, room), "hud",
                   palette.TEXT if visible else palette.TEXT_DIM, (sw.right + lh // 4, y))
        return y + lh

    def notes(self, surf, x: int, w: int, y: int, notes) -> int:
        """Warnings (switched off, slow, a failed reload), each wrapped to three lines."""
        sl = self.fonts["small"].get_linesize()
        for text in notes:
            if not text:
                continue
            for line in wrap_text(self.fonts["small"], text, w - 10)[:3]:
                self._blit(surf, line, "small", palette.WARN, (x + 10, y))
                y += sl
        return y

    def nees(self, surf, st, at, label: bool = True) -> pygame.Rect:
        """A FilterStatus's NEES (``label`` False: the value alone, :func:`nees_label`): the
        mean over the window, on the warning colour when above its band, outlined in it
        when below; before the window is full the tick's NEES, dimmed (no verdict)."""
        text = nees_label(st) if label else nees_label(st).removeprefix("NEES ")
        verdict = st.nees_verdict
        if verdict is None:
            dim = math.isnan(st.nees_mean)
            return self._blit(surf, text, "small", palette.TEXT_DIM if dim else palette.TEXT, at)
        if verdict == "high":
            return self._blit(surf, text, "small", palette.BANNER_TEXT, at, bg=palette.WARN)
        r = self._blit(surf, text, "small", palette.WARN, at)
        pygame.draw.rect(surf, palette.WARN, r.inflate(8, 2), 2)
        return r

    def footer(self, surf, rect: pygame.Rect, x: int, w: int, y: int, legend: list[str],
               info: dict) -> None:
        """The legend (what the shapes mean), FPS and recording, and the help hint, at the
        bottom of the panel (below ``y`` at least)."""
        f = self.fonts
        sl = f["small"].get_linesize()
        lines = [part for line in legend for part in wrap_text(f["small"], line, w)]
        rec = info.get("recording")
        lines.append(f"FPS {info.get('fps', 0):4.0f}")
        if info.get("mode") == "replay":
            lines[-1] += "   REPLAY"
        elif rec:  # the file's name (the folder is recordings/), its middle cut if need be
            name = getattr(rec, "name", str(rec))
            lines.append(fit_text(f["small"], f"REC {name}", rect.right - 16 - x))
        else:
            lines[-1] += "   not recording"
        y = max(y + 6, rect.bottom - (len(lines) + 1) * sl - 16)
        pygame.draw.line(surf, palette.GRID_MAJOR, (x, y), (rect.right - 12, y), 2)
        y += 6
        old_clip = surf.get_clip()
        surf.set_clip(rect.inflate(-6, 0))  # a long recording path is cut at the edge
        for line in lines:
            self._blit(surf, line, "small", palette.TEXT_DIM, (x, y))
            y += sl
        self._blit(surf, "H: help    Esc: quit", "small", palette.TEXT, (x, y))
        surf.set_clip(old_clip)

    def step_legend(self, surf, area: pygame.Rect, session, steps: bool, bound: bool,
                    avoid=(), world: pygame.Rect | None = None) -> pygame.Rect:
        """What the step view and the bound show, in a box at the bottom left of the world's
        area, or at its top left, where it covers none of the rectangles ``avoid`` (the axis
        labels) and, if it can, not the room (``world``); else raised above the labels it
        would cover. Returns the box."""
        lines = []
        if steps:
            used = sorted(session.used_ids()) if hasattr(session, "used_ids") else []
            lines.append(f"tick {session.tick_count} (t = {session.time:.2f} s):  dashed = after "
                         "predict (prior),  solid = after update (posterior)")
            lines.append(("update used beacons " + ", ".join(map(str, used)) + " (ringed)") if used
                         else "no reading on this tick: the update changed nothing")
        if bound:
            lines.append("dotted black around the robot: best achievable 95 % (PCRB)")
        font = self.fonts["small"]
        out: list[str] = []
        for line in lines:
            out += wrap_text(font, line, area.width - 40)
        lh = font.get_linesize()
        w, h = max(font.size(t)[0] for t in out) + 20, lh * len(out) + 10
        low = pygame.Rect(area.left + 8, area.bottom - 6 - h, w, h)
        high = pygame.Rect(area.left + 8, area.top + lh + 14, w, h)  # under "grid 2 m"
        free = [b for b in (low, high) if b.collidelist(list(avoid)) < 0]
        box = next((b for b in free if world is None or not b.colliderect(world)),
                   free[0] if free else low)
        covered = [r for r in avoid if r.colliderect(box)]
        if covered:
            box.bottom = min(r.top for r in covered) - 4
        shade = pygame.Surface(box.size, pygame.SRCALPHA)
        shade.fill((*palette.PANEL, 225))
        surf.blit(shade, box)
        pygame.draw.rect(surf, palette.PANEL_EDGE, box, 2)
        for k, t in enumerate(out):
            self._blit(surf, t, "small", palette.TEXT, (box.left + 10, box.top + 5 + k * lh))
        self.step_box = box
        return box

    def switched_off(self, surf, area: pygame.Rect, lines: list[tuple[str, tuple]],
                     avoid=(), keep_clear=()) -> pygame.Rect | None:
        """Switched-off filters said on the world, not only in the panel: a box at the bottom
        right of the world's area (bottom left where it would cover ``keep_clear``, the
        magnifier), a line per filter ``(text, colour)`` with a swatch of the
        filter's colour, raised above the axis labels (``avoid``) it would cover. Returns the
        box (None: no line)."""
        if not lines:
            return None
        font = self.fonts["small"]
        lh = font.get_linesize()
        sw = lh - 6  # the colour swatch [px]
        rows: list[tuple[str, tuple | None]] = []
        for text, colour in lines:
            for k, t in enumerate(wrap_text(font, text, area.width - 60 - sw)):
                rows.append((t, colour if k == 0 else None))
        w = max(font.size(t)[0] for t, _ in rows) + sw + 28
        h = lh * len(rows) + 10
        box = pygame.Rect(area.right - 8 - w, area.bottom - 6 - h, w, h)
        if box.collidelist(list(keep_clear)) >= 0:  # the magnifier there: the bottom left
            box.left = area.left + 8
        covered = [r for r in avoid if r.colliderect(box)]
        if covered:
            box.bottom = min(r.top for r in covered) - 4
        surf.fill(palette.PANEL, box)
        pygame.draw.rect(surf, palette.WARN, box, 3)
        for k, (t, swatch) in enumerate(rows):
            y = box.top + 5 + k * lh
            if swatch is not None:
                surf.fill(swatch, pygame.Rect(box.left + 10, y + 3, sw, sw))
            self._blit(surf, t, "small", palette.TEXT, (box.left + 18 + sw, y))
        self.off_box = box
        return box

    def banner(self, surf, area: pygame.Rect, text: str, avoid: pygame.Rect | None = None) -> None:
        """A large message across the top of the world view (kidnap, screenshot saved), or
        just under ``avoid`` (the robot) when at the top it would cover it."""
        font = "banner" if self.fonts["banner"].size(text)[0] <= area.width - 60 else "hud"
        lines = wrap_text(self.fonts[font], text, area.width - 60)[:4]
        imgs = [self.fonts[font].render(line, True, palette.BANNER_TEXT) for line in lines]
        if not imgs:
            return
        lh = self.fonts[font].get_linesize()
        r = pygame.Rect(0, 0, max(i.get_width() for i in imgs), lh * len(imgs))
        r.midtop = (area.centerx, area.top + 14)
        if avoid is not None and r.inflate(36, 16).colliderect(avoid):
            r.top = avoid.bottom + 16  # just under the robot (the bottom edge is the replay's)
            if r.inflate(36, 16).bottom > area.bottom:
                r.midbottom = (area.centerx, area.bottom - 14)
        box = r.inflate(36, 16)
        self.banner_box = box
        pygame.draw.rect(surf, palette.BANNER_BG, box, border_radius=10)
        pygame.draw.rect(surf, palette.TEXT, box, 3, border_radius=10)
        for k, img in enumerate(imgs):
            surf.blit(img, img.get_rect(midtop=(r.centerx, r.top + k * lh)))

    def help(self, surf) -> None:
        """Every binding of the mode's table (``controls.bindings``), grouped, over a dark
        translucent box, in one or two columns sized to their text: the panel's font if
        that fits the window, else the small one, descriptions wrapped if need be (nothing
        overlaps or is cut at 1024x768)."""
        W, H = surf.get_size()
        f = self.fonts
        lines = controls.help_lines(self.mode)
        groups: list[tuple[str, list[tuple[str, str]]]] = []
        for group, keys, desc in lines:
            if not groups or groups[-1][0] != group:
                groups.append((group, []))
            groups[-1][1].append((keys, desc))
        layout = self._help_layout(groups, W, H)
        font, ncol, key_w, desc_w, wrapped = layout
        lh = f[font].get_linesize()
        rows = [(g, [(k, wrapped[(k, d)], d) for k, d in rs]) for g, rs in groups]
        heights = [1.4 + sum(len(w) for _, w, _ in rs) for _, rs in rows]
        cols, tallest = split_columns(heights, ncol)
        col_w = key_w + desc_w + 30
        title_h = f["title"].get_linesize() + 22
        box = pygame.Rect(0, 0, col_w * ncol + 40, min(int(tallest * lh + title_h + 20), H - 10))
        box.center = (W // 2, H // 2)
        shade = pygame.Surface(box.size, pygame.SRCALPHA)
        shade.fill((*palette.OVERLAY_BG, 235))
        surf.blit(shade, box)
        pygame.draw.rect(surf, palette.OVERLAY_KEY, box, 3, border_radius=6)
        self._blit(surf, "Keys and mouse  (H or F1 closes)", "title", palette.OVERLAY_TEXT,
                   (box.left + 20, box.top + 12))
        self.help_drawn = []
        self.help_rects: list[pygame.Rect] = []  # every text drawn (tests: no overlap, inside)
        y0 = box.top + title_h
        y, col = y0, 0
        for (group, rs), c in zip(rows, cols, strict=True):
            if c != col:
                col, y = c, y0
            x = box.left + 20 + col * col_w
            self.help_rects.append(self._blit(surf, group, "small", palette.OVERLAY_KEY, (x, y)))
            y += max(int(lh * 1.1), f["small"].get_linesize() + 1)
            for keys, parts, desc in rs:
                self.help_rects.append(self._blit(surf, keys, font, palette.OVERLAY_KEY, (x, y)))
                for part in parts:
                    self.help_rects.append(self._blit(surf, part, font, palette.OVERLAY_TEXT,
                                                      (x + key_w, y)))
                    y += lh
                self.help_drawn.append((keys, desc))
            y += int(lh * 0.3)
        self.help_box = box

    def _help_layout(self, groups, W: int, H: int):
        """(font, columns, key column width, description width, {(keys, desc): lines}) for
        the help overlay: the largest font whose one or two columns fit ``W`` x ``H``."""
        f = self.fonts
        pairs = [kd for _, rs in groups for kd in rs]
        for font in ("hud", "small"):
            lh = f[font].get_linesize()
            key_w = max(f[font].size(k)[0] for k, _ in pairs) + 24
            title_h = f["title"].get_linesize() + 22
            for ncol in (1, 2):
                room = (W - 60) // ncol - 30 - key_w  # px for a description
                if room < 120:
                    continue
                wrapped = {(k, d): wrap_text(f[font], d, room) or [""] for k, d in pairs}
                desc_w = max(f[font].size(p)[0] for w in wrapped.values() for p in w)
                heights = [1.4 + sum(len(wrapped[kd]) for kd in rs) for _, rs in groups]
                _, tallest = split_columns(heights, ncol)
                if tallest * lh + title_h + 20 <= H - 10:
                    if font == "hud" and any(len(w) > 1 for w in wrapped.values()):
                        continue  # rather the small font on one line than the large one wrapped
                    return font, ncol, key_w, desc_w, wrapped
        font = "small"
        key_w = max(f[font].size(k)[0] for k, _ in pairs) + 24
        room = max((W - 60) // 2 - 30 - key_w, 80)
        wrapped = {(k, d): wrap_text(f[font], d, room) or [""] for k, d in pairs}
        desc_w = max(f[font].size(p)[0] for w in wrapped.values() for p in w)
        return font, 2, key_w, desc_w, wrapped


def beacons_in_view(session) -> tuple[list[int], int, set[int]]:
    """What the panel says is in view: the beacon IDs the readings carry (sorted), how many
    readings carry none (unknown correspondence, clutter included), and the beacons really
    seen (those IDs and, for readings without IDs, the beacons they came from: the
    simulator's truth, ``association_layer.seen_by_truth``), so none of them is "missed"."""
    labelled: set[int] = set()
    unlabelled = 0
    for m in session.readings():
        if m.kind.startswith("robot_"):
            continue
        ids = np.asarray(m.beacon_ids, dtype=np.int64)
        labelled |= {int(i) for i in ids[ids != UNKNOWN_ID]}
        unlabelled += int(np.count_nonzero(ids == UNKNOWN_ID))
    return sorted(labelled), unlabelled, labelled | association_layer.seen_by_truth(session)


def kind_lines(session) -> list[str]:
    """The panel's line for each sensor of a kind registered beside the built-in ones
    (core/sensor_kinds.py): ``<kind label> (<sensor>): <rows> readings`` of this tick."""
    rows: dict[str, int] = {}
    for m in session.readings():
        rows[m.sensor] = rows.get(m.sensor, 0) + len(m)
    out = []
    for s in session.scenario.sensors:
        kind = sensor_kinds.KINDS.get(s.kind)
        if kind is not None and s.kind not in sensor_kinds.BUILTIN:
            n = rows.get(s.name, 0)
            out.append(f"{kind.label or kind.name} ({s.name}): {n} reading{'s' if n != 1 else ''}")
    return out


def scan_in_view(session) -> tuple[int, int]:
    """What the panel says the range finder senses: the beams of this tick's scans and how
    many of them hit something (read less than the sensor's max range)."""
    spec = {s.name: s for s in session.scenario.sensors}
    beams = hits = 0
    for m in session.readings():
        if not is_scan(m.kind):
            continue
        r = np.asarray(m.z, dtype=float)[:, 0]
        beams += len(r)
        s = spec.get(m.sensor)
        hits += int(np.count_nonzero(r < s.max_range)) if s is not None else len(r)
    return beams, hits


def ids_text(labelled: list[int], unlabelled: int) -> str:
    """The panel's line under "beacons in view": ``  IDs 1, 4``, ``  no IDs (3 readings)``,
    both when sensors of both kinds read, or ``  IDs none``."""
    parts = []
    if labelled:
        parts.append("IDs " + ", ".join(map(str, labelled)))
    if unlabelled:
        parts.append(f"no IDs ({unlabelled} reading{'s' if unlabelled != 1 else ''})")
    return "  " + ("; ".join(parts) if parts else "IDs none")


def split_columns(heights: list[float], ncol: int) -> tuple[list[int], float]:
    """Groups of ``heights`` rows, in order, into ``ncol`` (1 or 2) columns without splitting
    a group: (each group's column, the taller column's rows). Two columns: the split that
    makes the taller one shortest."""
    if ncol == 1 or len(heights) < 2:
        return [0] * len(heights), float(sum(heights))
    best = min(range(1, len(heights)),
               key=lambda k: max(sum(heights[:k]), sum(heights[k:])))
    return ([0] * best + [1] * (len(heights) - best),
            float(max(sum(heights[:best]), sum(heights[best:]))))


#: A filter is said to claim more than is possible when its position sigma is below this
#: share of the bound's (a few per cent either way are the two models' rounding).
INSIDE_BOUND = 0.9


def inside_the_bound(session, bound_sigma: float) -> list[str]:
    """The shown filters whose position sigma [m] is below the best achievable one (the
    PCRB's, ``bound_sigma``): a filter told a model that loses uncertainty (the classroom
    KF's A = I never turns heading uncertainty into position uncertainty, which the bound's
    motion Jacobian does) claims more than is possible."""
    out = []
    for name in session.names:
        st = session.status[name]
        if (session.visible[name] and not st.failed and math.isfinite(st.pos_sigma)
                and st.pos_sigma < INSIDE_BOUND * bound_sigma):
            out.append(name)
    return out


def nees_label(st) -> str:
    """What the panel writes for a FilterStatus's NEES: the window's mean (``NEES 2.9``), or
    before the window is full the tick's value (``NEES 0.0``, dimmed)."""
    value = st.nees if math.isnan(st.nees_mean) else st.nees_mean
    return nees_text(value)


def nees_legend() -> list[str]:
    """The panel's lines saying what the NEES figure and its badge mean."""
    lo, hi = NEES_WINDOW_BAND
    return [f"NEES: {NEES_WINDOW_S:.0f} s mean; orange > {hi:.2f}, outlined < {lo:.2f}"]


def nees_text(nees: float) -> str:
    """``NEES 2.1``, ``NEES 345``, ``NEES >1000``."""
    v = f"{nees:.1f}" if nees < 100 else (f"{nees:.0f}" if nees < 1000 else ">1000")
    return f"NEES {v}"


def fps_of(frame_times: np.ndarray) -> float:
    """Frames per second from recent frame durations [s]."""
    if not len(frame_times):
        return 0.0
    m = float(np.mean(frame_times))
    return 1.0 / m if m > 0 else 0.0
