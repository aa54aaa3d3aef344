"""The side panel: the scenario's name and clock, the command and who drives, what the robot
senses, each filter's error, sigma and NEES badge (or why it was switched off), the bound, and
at the bottom the legend, FPS and recording. A team's panel has a column per robot.
"""

from __future__ import annotations

import math

import numpy as np
import pygame

from beacon_sim.app import palette
from beacon_sim.app.estimate_layer import ELLIPSE_LEVEL, ELLIPSE_SCALE2
from beacon_sim.app.in_view import (
    beacons_in_view,
    ids_text,
    kind_lines,
    missed_ids,
    scan_in_view,
    sensors_read,
)
from beacon_sim.app.panel_cache import KeptPanel, draw_line, draw_outline, volatile
from beacon_sim.app.text import TextPainter, fit_text, short, wrap_text
from beacon_sim.core.clutter import UNKNOWN_ID
from beacon_sim.core.sensor_kinds import scan_sensors
from beacon_sim.runs.scene import NEES_WINDOW_BAND, NEES_WINDOW_S, Scene

#: The panel says the delivered speed when it is below this fraction of the asked one.
SHORT_OF_SPEED = 0.9


class Panel(TextPainter):
    """The panel of one robot (:meth:`panel`) or of a team (:meth:`team_panel`), and its pieces."""

    def __init__(self, fonts: dict[str, pygame.font.Font]):
        super().__init__(fonts)
        #: The panel's picture, kept while it says the same (``panel_cache``); ``keep_panel``
        #: False draws it straight onto the screen every frame.
        self.kept_panel = KeptPanel()
        self.keep_panel = True

    def panel(self, surf, rect: pygame.Rect, session: Scene, colours, info: dict) -> None:
        """The side panel. ``info``: speed, paused, fps, recording (path or None), message.
        A team's panel is :meth:`team_panel`. Drawn from the kept picture when it says what
        it said the frame before (``panel_cache.KeptPanel``)."""
        if not self.keep_panel:
            self.draw_panel(surf, rect, session, colours, info)
            return
        self.kept_panel.show(surf, rect, lambda target: self.draw_panel(target, rect, session, colours, info))

    def draw_panel(self, surf, rect: pygame.Rect, session: Scene, colours, info: dict) -> None:
        """:meth:`panel`'s drawing onto ``surf`` (a surface, or a ``panel_cache.PanelOps``)."""
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
            "black outline: true robot; line: path",
            *nees_legend(),  # (last: a full panel drops the legend's last lines)
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

    def begin_panel(self, surf, rect: pygame.Rect) -> tuple[int, int, int]:
        """The panel's background and left edge; returns (x, text width, y) [px]."""
        surf.fill(palette.PANEL, rect)
        draw_line(surf, palette.PANEL_EDGE, rect.topleft, rect.bottomleft, 3)
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
        draw_line(surf, palette.GRID_MAJOR, (x, y), (rect.right - 12, y), 2)
        return y + 8

    def filter_label(self, surf, x: int, y: int, i: int, name: str, colour, visible: bool) -> int:
        """A filter's swatch (filled when shown), its number (the 1-9 key) and name."""
        lh = self.fonts["hud"].get_linesize()
        sw = pygame.Rect(x, y + 4, round(lh * 0.65), lh - 8)
        if visible:
            surf.fill(colour, sw)
        draw_outline(surf, colour, sw, 3)
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
        draw_outline(surf, palette.WARN, r.inflate(8, 2), 2)
        return r

    def footer(self, surf, rect: pygame.Rect, x: int, w: int, y: int, legend: list[str],
               info: dict) -> None:
        """The legend (what the shapes mean), FPS and recording, and the help hint, at the
        bottom of the panel (below ``y`` at least)."""
        f = self.fonts
        sl = f["small"].get_linesize()
        notes = [part for line in legend for part in wrap_text(f["small"], line, w)]
        rec = info.get("recording")
        status = [f"FPS {info.get('fps', 0):4.0f}"]
        if info.get("mode") == "replay":
            status[-1] += "   REPLAY"
        elif rec:  # the file's name (the folder is recordings/), its middle cut if need be
            name = getattr(rec, "name", str(rec))
            status.append(fit_text(f["small"], f"REC {name}", rect.right - 16 - x))
        else:
            status[-1] += "   not recording"
        # A full panel (a team's at 1920x1080: a block per filter) keeps the status and the
        # help hint and drops the legend's last lines (the help overlay, H, says it all).
        room = (rect.bottom - 16 - (y + 6) - 6) // sl - 1 - len(status)
        lines = notes[:max(room, 0)] + status
        y = max(y + 6, rect.bottom - (len(lines) + 1) * sl - 16)
        draw_line(surf, palette.GRID_MAJOR, (x, y), (rect.right - 12, y), 2)
        y += 6
        old_clip = surf.get_clip()
        surf.set_clip(rect.inflate(-6, 0))  # a long recording path is cut at the edge
        for i, line in enumerate(lines):
            if i == len(lines) - len(status):  # the FPS: a new figure every frame, drawn apart
                with volatile(surf):
                    self._blit(surf, line, "small", palette.TEXT_DIM, (x, y))
            else:
                self._blit(surf, line, "small", palette.TEXT_DIM, (x, y))
            y += sl
        self._blit(surf, "H: help    Esc: quit", "small", palette.TEXT, (x, y))
        surf.set_clip(old_clip)


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
    return [f"NEES: {NEES_WINDOW_S:.0f} s mean; orange > {hi:.2f}, outlined < {lo:.2f}",
            "(a standstill widens the band)"]


def nees_text(nees: float) -> str:
    """``NEES 2.1``, ``NEES 345``, ``NEES >1000``."""
    v = f"{nees:.1f}" if nees < 100 else (f"{nees:.0f}" if nees < 1000 else ">1000")
    return f"NEES {v}"
