"""Metres to pixels, and drawing the world: grid, beacons, sensor disc, rays, trails,
beliefs (ellipses, heading wedges, particles, heat maps) and the true robot.

All geometry arrives in metres from the core (``geometry``) or ``shapes``; this module only
converts to pixels and draws. The screen's y axis points down; the world's points up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pygame

from beacon_sim.app import association_layer, distance_layer, map_view, palette, shapes
from beacon_sim.app.map_layer import MapLayer
from beacon_sim.core.geometry import CHI2_2DOF, circle, covariance_ellipse
from beacon_sim.core.schedule import period_ticks
from beacon_sim.core.sensor_kinds import is_scan
from beacon_sim.core.sensors import visible_beacons
from beacon_sim.core.world import World
from beacon_sim.filters.base import GridBelief, ParticleBelief
from beacon_sim.runs.scene import Scene
from beacon_sim.runs.styles import BOUND_STYLE

#: The 95 % ellipse of x-y: chi-square quantile for 2 degrees of freedom.
ELLIPSE_LEVEL = 0.95
ELLIPSE_SCALE2 = CHI2_2DOF[ELLIPSE_LEVEL]
#: The step view's prior (after predict): dashed, as in the textbook figures [px on, off].
PRIOR_DASH = (14, 10)
#: The magnifier's words above the sizes of the ellipses it shows.
MAGNIFIER_HEADING = "95 % ellipse, across:"
MAGNIFIER_BOUND = "best possible (PCRB)"
#: Below this size [px] in the magnifier the bound gets its own closer look (a box inside).
MIN_BOUND_PX = 30.0
#: A beacon in a sensor's range that was not detected: a dashed ring [px on, off].
MISSED_DASH = (6, 5)


class View:
    """Maps world metres to window pixels inside ``area`` (x, y, w, h), with zoom and pan.

    ``scale`` is pixels per metre; ``centre`` the world point [m] shown at the area's centre.
    """

    def __init__(self, bounds, area: tuple[int, int, int, int]):
        self.bounds = tuple(float(b) for b in bounds)
        self.area = area
        self.scale = 1.0
        self.centre = np.zeros(2)
        self.fit()

    def set_area(self, area: tuple[int, int, int, int]) -> None:
        self.area = area
        self.fit()

    def fit(self) -> None:
        """Show the whole world with a margin for the axis labels."""
        xmin, ymin, xmax, ymax = self.bounds
        _, _, w, h = self.area
        pad = 44  # px for labels and air
        self.scale = max(min((w - 2 * pad) / (xmax - xmin), (h - 2 * pad) / (ymax - ymin)), 1e-3)
        self.centre = np.array([(xmin + xmax) / 2, (ymin + ymax) / 2])

    @property
    def key(self) -> tuple:
        """Changes whenever the mapping changes (for caches)."""
        return (self.area, round(self.scale, 9), float(self.centre[0]), float(self.centre[1]))

    def to_px(self, xy) -> np.ndarray:
        """World points (..., 2) [m] -> pixel coordinates (..., 2), float."""
        xy = np.asarray(xy, dtype=float)
        ax, ay, w, h = self.area
        out = np.empty_like(xy)
        out[..., 0] = ax + w / 2 + (xy[..., 0] - self.centre[0]) * self.scale
        out[..., 1] = ay + h / 2 - (xy[..., 1] - self.centre[1]) * self.scale
        return out

    def to_world(self, px) -> np.ndarray:
        """Pixel coordinates (..., 2) -> world points [m]."""
        px = np.asarray(px, dtype=float)
        ax, ay, w, h = self.area
        out = np.empty_like(px)
        out[..., 0] = self.centre[0] + (px[..., 0] - ax - w / 2) / self.scale
        out[..., 1] = self.centre[1] - (px[..., 1] - ay - h / 2) / self.scale
        return out

    def zoom(self, factor: float, at_px) -> None:
        """Zoom by ``factor`` keeping the world point under ``at_px`` in place."""
        before = self.to_world(at_px)
        self.scale = float(np.clip(self.scale * factor, 2.0, 20000.0))
        after = self.to_world(at_px)
        self.centre = self.centre + (before - after)

    def pan(self, dx_px: float, dy_px: float) -> None:
        """Move the picture by (dx, dy) pixels."""
        self.centre = self.centre + np.array([-dx_px, dy_px]) / self.scale

    def visible_world(self) -> tuple[float, float, float, float]:
        """The world rectangle (xmin, ymin, xmax, ymax) [m] the area shows."""
        ax, ay, w, h = self.area
        (x0, y1), (x1, y0) = self.to_world(np.array([[ax, ay], [ax + w, ay + h]]))
        return x0, y0, x1, y1


@dataclass
class ShowOptions:
    particles: bool = True
    trails: bool = True
    ellipses: bool = True
    chart: bool = False  # the strip chart of error and 2-sigma (C)
    step: bool = True  # while paused: the last tick's prior and posterior (V)
    bound: bool = False  # the best achievable covariance, the PCRB (B)
    field: bool = False  # a map world's likelihood field under the walls (L)
    hdop: bool = False  # distance beacons: the floor shaded by the layout's HDOP (O)


def line_width(height_px: int) -> int:
    """Belief line width [px] for a window ``height_px`` tall: 4 px at 800, more above."""
    return max(4, round(height_px / 200))


def polyline(surf, colour, pts, width: int, dash=None, closed: bool = False) -> None:
    """A thick polyline through ``pts`` (k, 2) [px], solid (``dash`` None) or dashed with
    the pattern ``dash`` (px on, px off, ...), measured along the line."""
    pts = np.asarray(pts, dtype=float)
    if closed:
        pts = np.vstack([pts, pts[:1]])
    if len(pts) < 2:
        return
    if dash is None:
        pygame.draw.lines(surf, colour, False, pts, width)
        if len(pts) > 200:
            return
        # Round joints: thick pygame lines leave notches at corners. A thick line is drawn as
        # 1 px lines side by side, offset along x or along y by its slope, so a notch is left
        # where the line turns or where the offset's axis changes; elsewhere (most vertices of
        # a 96-point ellipse) the next segment covers the joint and no circle is drawn.
        for x, y in pts[1:-1][notched_joints(pts)].tolist():
            pygame.draw.circle(surf, colour, (ipx(x), ipx(y)), max(width // 2 - 1, 1))
        return
    seg = np.hypot(*np.diff(pts, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    total = float(s[-1])
    if not total > 0:
        return
    step = max(total / 4000.0, 1.5)  # sample every ~2 px (at most 4000 samples)
    t = np.arange(0.0, total + step, step)
    t[-1] = min(t[-1], total)
    xs, ys = np.interp(t, s, pts[:, 0]), np.interp(t, s, pts[:, 1])
    period = float(sum(dash))
    bounds = np.cumsum(dash)
    phase = np.searchsorted(bounds, t % period, side="right")
    on = phase % 2 == 0
    edges = np.flatnonzero(np.diff(np.concatenate([[0], on.astype(np.int8), [0]]))).tolist()
    xy = np.stack([xs, ys], 1).tolist()  # one conversion, then slices (no array per dash)
    r = max(width // 2, 1)
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        if b - a >= 2:
            pygame.draw.lines(surf, colour, False, xy[a:b], width)
        else:
            pygame.draw.circle(surf, colour, xy[a], r)


#: A joint turning by more than this [rad] gets a round cap (see :func:`polyline`).
JOINT_TURN = math.radians(8.0)


def notched_joints(pts: np.ndarray) -> np.ndarray:
    """Which interior vertices of the polyline ``pts`` (k, 2) [px] a thick pygame line leaves
    a notch at: a turn of more than ``JOINT_TURN``, or the segments on either side drawn
    with their 1 px strokes offset along different axes (one steeper than 45 degrees, one
    not). Zero-length segments count as turns. Returns a boolean mask of k - 2 entries."""
    d = np.diff(pts, axis=0)
    a, b = d[:-1], d[1:]
    cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    dot = (a * b).sum(axis=1)
    turn = np.abs(np.arctan2(cross, dot))
    steep = np.abs(d[:, 1]) > np.abs(d[:, 0])
    degenerate = ~((a != 0).any(axis=1) & (b != 0).any(axis=1))
    return (turn > JOINT_TURN) | (steep[:-1] != steep[1:]) | degenerate


def ipx(v) -> int:
    """Round a pixel coordinate to the nearest integer."""
    return math.floor(float(v) + 0.5)


def sensors_read(scenario, tick: int) -> list:
    """The scenario's sensors that have been read by ``tick`` (one period has passed): before
    its first reading a sensor has missed nothing."""
    return [s for s in scenario.sensors if tick >= period_ticks(s.period, scenario.dt)]


def missed_ids(sensors, world, pose, seen) -> set[int]:
    """IDs of the beacons within some beacon sensor's range and field of view at the true
    ``pose`` that are not in ``seen`` (missed by detection probability, or blacked out)."""
    ids = np.array([b.id for b in world.beacons], dtype=np.int64)
    if not len(ids):
        return set()
    inside = np.zeros(len(ids), dtype=bool)
    for spec in sensors:  # every kind of sensor detects beacons one by one
        inside |= visible_beacons(spec, np.asarray(pose, dtype=float), world)
    return {int(i) for i in ids[inside]} - set(seen)


def ellipse_diameter(cov) -> float:
    """The major axis [m] of the 95 % ellipse of the x-y block of ``cov``."""
    c = np.asarray(cov, dtype=float)[:2, :2]
    if not np.all(np.isfinite(c)):
        return math.inf
    return 2.0 * math.sqrt(max(float(np.linalg.eigvalsh(c)[-1]), 0.0) * ELLIPSE_SCALE2)


def format_length(metres: float) -> str:
    """``4 cm``, ``0.5 mm``, ``1.2 m``: a length in the unit that reads best."""
    if metres >= 1.0:
        return f"{metres:.2g} m"
    if metres >= 0.01:
        return f"{metres * 100:.2g} cm"
    return f"{metres * 1000:.2g} mm"


def nice_step(scale: float, min_px: float = 70.0) -> float:
    """Grid spacing [m] from 1-2-5 steps so that lines are at least ``min_px`` apart."""
    target = min_px / scale
    exp = math.floor(math.log10(target))
    for m in (1.0, 2.0, 5.0, 10.0):
        step = m * 10.0**exp
        if step >= target - 1e-12:
            return step
    return 10.0 ** (exp + 1)


#: The steps of :meth:`WorldRenderer.phases` (the yields plus the last part).
PHASES = 5


#: A team's estimate arrows at this fraction of a single robot's: a few filters' arrows on
#: one robot leave its outline visible.
TEAM_ARROW_SCALE = 0.65


class WorldRenderer:
    """Draws one frame of the world into a surface (the HUD is drawn by ``hud``)."""

    def __init__(self, fonts: dict[str, pygame.font.Font]):
        self.fonts = fonts
        self._heat_cache: dict[str, tuple[tuple, pygame.Surface, tuple[int, int]]] = {}
        self._text_cache: dict[tuple, pygame.Surface] = {}
        self._static: tuple[tuple, pygame.Surface] | None = None
        self.last_world: World | None = None  # the world of the scene being drawn (step view)
        self.last_world_sensors: tuple = ()   # its sensors (a scan's max range)
        self.lw = 4  # line width [px]; each frame's begin() sets it for the window's height
        self.show_field = False  # the likelihood field under the walls (ShowOptions.field)
        self.map_layer = MapLayer()  # SLAM filters' estimated maps (app/map_layer.py)
        self.hdop_layer = distance_layer.HdopShading()  # distance beacons' HDOP floor (O)
        self.last_magnifier: dict | None = None  # what the magnifier drew (see magnifier)
        # the live PCRB (3, 3) the window shows (B), or None: the magnifier draws it too
        self.bound_cov: np.ndarray | None = None
        self.axis_rects: list[pygame.Rect] = []  # the axis labels of the static layer [px]
        self.beacon_rects: list[pygame.Rect] = []  # beacons and their labels, last drawn [px]

    def text(self, s: str, font: str, colour) -> pygame.Surface:
        key = (s, font, colour)
        surf = self._text_cache.get(key)
        if surf is None:
            if len(self._text_cache) > 512:
                self._text_cache.clear()
            surf = self.fonts[font].render(s, True, colour)
            self._text_cache[key] = surf
        return surf

    # --- the frame ------------------------------------------------------------------------
    def draw(self, surf: pygame.Surface, view: View, session: Scene, colours, show: ShowOptions,
             drag=None, dashes=None, extra=None) -> None:
        """Draw the world part of a frame. ``drag``: (start_px, now_px) of a click-kidnap.
        ``dashes``: filter name -> dash pattern (None: solid). ``extra``: a callable
        ``(surf, view, lw)`` drawn after the truth and before the beliefs (the step view's
        prior ellipses, the bound's ellipse).

        Order: the true robot is an outline drawn UNDER every belief, and the ellipses and
        wedges come last, solid ones first, so that nothing hides an estimate."""
        if getattr(session, "n_robots", 1) > 1:
            self.draw_team(surf, view, session, colours, show, drag, dashes, extra)
            return
        for _ in self.phases(surf, view, session, colours, show, drag, dashes, extra):
            pass

    def phases(self, surf: pygame.Surface, view: View, session: Scene, colours, show: ShowOptions,
               drag=None, dashes=None, extra=None):
        """:meth:`draw` as a generator of :data:`PHASES` steps, in the order of :meth:`draw`:
        each ``next`` draws one more layer (the floor and the heat maps, the trails, rays,
        beacons and the true robot, the particles, ``extra`` and the estimates, the
        magnifier), all from the same session state (the window spreads them over two
        frames). The clip is restored when it ends or is closed half way. A team's world
        (:meth:`team_phases`) takes fewer steps."""
        if getattr(session, "n_robots", 1) > 1:  # a team's world, in its own steps
            yield from self.team_phases(surf, view, session, colours, show, drag, dashes, extra)
            return
        sc = session.scenario
        self.last_world = sc.world
        self.last_world_sensors = sc.sensors
        self.show_field = show.field
        pose = session.true_pose
        dashes = dashes or {}
        old_clip = self.begin(surf, view)
        try:
            self.sensor_discs(surf, view, sc.sensors, pose)
            if show.hdop:
                self.hdop_layer.draw(surf, view, sc.world, sc.sensors,
                                     self._world_rect(view).clip(surf.get_clip()))
            beliefs = {}
            for name in session.names:
                if not session.visible[name] or session.status[name].failed:
                    continue
                try:
                    beliefs[name] = session.belief(name)
                except Exception as exc:  # a student's belief(): show it, keep the window alive
                    session.status[name].failed = f"belief(): {type(exc).__name__}: {exc}"
            for name, bel in beliefs.items():
                if isinstance(bel, GridBelief):
                    self._heat(surf, view, name, bel, colours[name], session.tick_count)
            yield
            if show.trails:
                self.trail(surf, view, session.truth_trail, palette.TRUTH_TRAIL, 5)
                for name in session.names:
                    if session.visible[name]:
                        self.trail(surf, view, session.trail(name), colours[name], 2)
            self.rays(surf, view, sc.world, pose, session.readings())
            distance_layer.readings(surf, view, sc.world, sc.sensors, pose, session.readings(), self.lw,
                                    polyline)
            seen = session.seen_ids() | association_layer.seen_by_truth(session)  # + those read without IDs
            self.beacons(surf, view, sc.world, seen,
                         missed_ids(sensors_read(sc, session.tick_count), sc.world, pose, seen))
            self.robot(surf, view, pose, sc.robot_radius)  # the truth UNDER every belief
            yield
            if show.particles:
                for name, bel in beliefs.items():
                    if isinstance(bel, ParticleBelief):
                        self.particles(surf, view, bel.poses, colours[name], bel.weights)
            yield
            if extra is not None:
                extra(surf, view, self.lw)
            if show.ellipses:
                self.map_layer.draw(surf, view, session, list(beliefs), colours, dashes, self.lw, polyline)
            association_layer.draw(surf, view, session, colours, self.lw, polyline)  # reading -> its beacon
            estimates = []
            for name in session.names:
                if name not in beliefs:
                    continue
                try:
                    est = session.estimate(name)
                except Exception:  # before the first tick a student's estimate() may raise
                    continue
                if est is not None:
                    estimates.append((name, *est))
            self.estimates(surf, view, estimates, colours, dashes, sc.robot_radius, show.ellipses)
            yield
            self.last_magnifier = None
            if show.ellipses:
                self.magnifier(surf, view, pose, estimates, colours, dashes, sc.robot_radius)
            if drag is not None:
                self._drag_ghost(surf, view, drag, pose, sc.robot_radius)
            if show.hdop and distance_layer.distance_sensor(sc.sensors) is not None:
                spec = distance_layer.distance_sensor(sc.sensors)
                self.hdop_layer.key_box(surf, self._world_rect(view).clip(surf.get_clip()),
                                        self.fonts["small"], spec.kind)
        finally:
            surf.set_clip(old_clip)

    # --- the pieces every window draws (the single-robot and the team window) --------------

    def draw_team(self, surf, view, session, colours, show, drag=None, dashes=None,
                  extra=None) -> None:
        """The world of a team (``session.n_robots`` > 1): every robot, ringed and tagged,
        the driven one on a halo; each filter's estimate of each robot (arrow and x-y
        ellipse, no heading wedges); beacon and robot-to-robot readings."""
        for _ in self.team_phases(surf, view, session, colours, show, drag, dashes, extra):
            pass

    def team_phases(self, surf, view, session, colours, show, drag=None, dashes=None, extra=None):
        """:meth:`draw_team` as a generator of two steps (see :meth:`phases`)."""
        self.last_world = session.team.world
        self.show_field = show.field
        dashes = dashes or {}
        old_clip = self.begin(surf, view)
        try:
            yield from self._team_layers(surf, view, session, colours, show, drag, dashes, extra)
        finally:
            surf.set_clip(old_clip)

    def _team_layers(self, surf, view, session, colours, show, drag, dashes, extra):
        """:meth:`team_phases`' layers, inside the clip: the floor's pieces, the readings and
        the robots; then the beliefs, the rings and the tags."""
        team = session.team
        poses = session.poses
        radii = [r.scenario.robot_radius for r in team.robots]
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
        yield
        if extra is not None:
            extra(surf, view, self.lw)
        beliefs = {name: session.estimates(name) for name in shown}
        for i, radius in enumerate(radii):
            ests = [(name, est[0][i], est[1][i]) for name, est in beliefs.items() if est is not None]
            # smaller arrows than alone and no heading wedges: a dozen beliefs on three robots
            self.estimates(surf, view, ests, colours, dashes, radius, show.ellipses, TEAM_ARROW_SCALE,
                           wedges=False)
        self.tags: list[pygame.Rect] = []
        for i, (r, pose) in enumerate(zip(team.robots, poses, strict=True)):
            self.robot_ring(surf, view, pose, radii[i])
            self.name_tag(surf, view, pose, radii[i], r.name, i == session.driven)
        if drag is not None:
            self._drag_ghost(surf, view, drag, session.true_pose, radii[session.driven])

    def robot_rays(self, surf, view, session, pose, readings) -> None:
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

    def begin(self, surf: pygame.Surface, view: View) -> pygame.Rect:
        """Start a frame of the world: the line width for the window's height, the static
        layer (background, grid, bounds, labels), the clip set to the view's area. Returns
        the clip to restore when done."""
        self.lw = line_width(surf.get_height())
        area = pygame.Rect(view.area)
        old_clip = surf.get_clip()
        surf.set_clip(area)
        surf.blit(self._static_layer(view, self._world_rect(view)), area)
        return old_clip

    def estimates(self, surf, view: View, estimates, colours, dashes, radius: float,
                  ellipses: bool = True, arrow: float = 1.0, wedges: bool = True) -> None:
        """Estimates ``(key, mean, cov)``: an arrow each in ``colours[key]`` (``arrow`` times
        the usual size), then (with ``ellipses``) the 95 % ellipses and (with ``wedges``)
        heading wedges in ``dashes[key]`` style, solid ones first: a dashed one drawn over a
        solid one leaves gaps to see it through."""
        for key, mean, _ in estimates:
            self._arrow(surf, view, mean, colours[key], radius, arrow)
        if ellipses:
            order = sorted(estimates, key=lambda e: dashes.get(e[0]) is not None)
            if wedges:  # every wedge first: a small ellipse is never under a wedge
                for key, mean, cov in order:
                    self.uncertainty(surf, view, mean, cov, colours[key], dashes.get(key), radius,
                                     wedge=True, ellipse=False)
            xmin, ymin, xmax, ymax = view.bounds
            too_big = math.hypot(xmax - xmin, ymax - ymin)  # a 95 % ellipse wider than the world
            self._lost_labels: list[pygame.Rect] = []
            shown = []
            for key, mean, cov in order:
                across = ellipse_diameter(cov)
                if not across <= too_big:  # lost (or not a number): a marker, not lines
                    self.lost_marker(surf, view, key, mean, across, colours[key], dashes.get(key))
                else:
                    shown.append((key, mean, cov))
            self._ellipses(surf, view, shown, colours, dashes)

    def _ellipses(self, surf, view: View, estimates, colours, dashes) -> None:
        """The 95 % ellipses of ``estimates`` (solid ones first). Ellipses that lie on one
        another (every point within a line width) are drawn in stripes, each colour in turn
        along the outline and an equal share of it, with a note naming them: one drawn over
        the other hid it (a dashed one left the other only its gaps)."""
        lw = self.lw
        outlines = [view.to_px(covariance_ellipse(mean[:2], cov[:2, :2], ELLIPSE_SCALE2, 96))
                    for _, mean, cov in estimates]
        groups: list[list[int]] = []
        for i in range(len(estimates)):
            if np.all(np.isfinite(outlines[i])):
                for g in groups:
                    if np.max(np.hypot(*(outlines[g[0]] - outlines[i]).T)) <= lw:
                        g.append(i)
                        break
                else:
                    groups.append([i])
        striped = {i: (g.index(i), len(g)) for g in groups if len(g) > 1 for i in g}
        for i, (key, mean, cov) in enumerate(estimates):
            if i not in striped:
                self.uncertainty(surf, view, mean, cov, colours[key], dashes.get(key), 0.0, wedge=False)
        for g in groups:
            if len(g) < 2:
                continue
            pts = outlines[g[0]]
            seg = 3.0 * lw
            arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
            polyline(surf, colours[estimates[g[0]][0]], pts, lw, None, closed=True)
            for k, i in enumerate(g[1:]):
                # the same outline in stripes over the first, each started a stripe further
                # on: the colours take turns (two: exactly, half and half)
                start = int(np.searchsorted(arc, (k * seg) % max(arc[-1], 1e-9)))
                polyline(surf, colours[estimates[i][0]], np.roll(pts, -start, axis=0), lw,
                         (seg, (len(g) - 1) * seg), closed=True)
            if max(np.ptp(pts[:, 0]), np.ptp(pts[:, 1])) < 80:  # under the robot: the magnifier's
                continue
            names = ", ".join(estimates[i][0] for i in g)
            img = self.text(f"{names}: same ellipse", "small", palette.TEXT)
            top = pts[int(np.argmin(pts[:, 1]))]
            box = img.get_rect(midbottom=(ipx(top[0]), ipx(top[1]) - lw - 2)).inflate(8, 2)
            box.clamp_ip(surf.get_clip())
            surf.fill(palette.PANEL, box)
            surf.blit(img, img.get_rect(center=box.center))

    def lost_marker(self, surf, view: View, key: str, mean, across: float, colour, dash) -> None:
        """A belief whose 95 % ellipse is wider than the world (``across`` [m]): instead of
        lines crossing the world and its margins, a ring at the estimate (kept inside the
        world) with four ticks pointing out, and a label beside it that keeps off the other
        such labels: "dead_reckoning: 95 % ellipse 16 m, wider than the world"."""
        xmin, ymin, xmax, ymax = view.bounds
        at = np.array([min(max(float(mean[0]), xmin), xmax), min(max(float(mean[1]), ymin), ymax)])
        c = view.to_px(at) if np.all(np.isfinite(at)) else view.to_px(np.array([xmin, ymax]))
        r = 22.0
        ring = circle(np.asarray(c, dtype=float), r, 48)
        polyline(surf, colour, ring, self.lw, dash, closed=True)
        for a in (0.25, 0.75, 1.25, 1.75):  # ticks pointing out: the belief goes on beyond
            d = np.array([math.cos(a * math.pi), math.sin(a * math.pi)])
            pygame.draw.line(surf, colour, c + d * (r + 3), c + d * (r + 13), max(self.lw - 1, 2))
        size = f"{across:.0f} m, wider than the world" if math.isfinite(across) else "not a number"
        img = self.text(f"{key}: 95 % ellipse {size}", "small", palette.TEXT)
        clip = surf.get_clip()
        taken = self._lost_labels
        cx, cy, step = ipx(c[0]), ipx(c[1]), img.get_height() + 8
        box = None
        world = self._world_rect(view)
        for k in range(4):  # first in the margins above and under the world: it hides nothing
            spot = img.get_rect(midbottom=(cx, world.top - 8 - k * step)) if k % 2 == 0 \
                else img.get_rect(midtop=(cx, world.bottom + 30 + (k // 2) * step))
            spot = spot.inflate(10, 4)
            spot.clamp_ip(pygame.Rect(world.left, clip.top, world.width, clip.height).clip(clip))
            if clip.contains(spot) and not spot.colliderect(world) and spot.collidelist(taken) < 0:
                box = spot
                break
        for k in range(12 if box is None else 0):  # beside the ring (right, left), further down, up
            dy = (k // 2 + 1) // 2 * step * (1 if (k // 2) % 2 else -1)
            spot = img.get_rect(midleft=(cx + ipx(r) + 18, cy + dy)) if k % 2 == 0 \
                else img.get_rect(midright=(cx - ipx(r) - 18, cy + dy))
            spot = spot.inflate(10, 4)
            if clip.contains(spot) and spot.collidelist(taken) < 0:
                box = spot
                break
        if box is None:
            box = img.get_rect(midleft=(cx + ipx(r) + 18, cy)).inflate(10, 4)
            box.clamp_ip(clip)
        taken.append(box)
        surf.fill(palette.PANEL, box)
        pygame.draw.rect(surf, colour, box, 2)
        surf.blit(img, img.get_rect(center=box.center))

    def trail(self, surf, view: View, trail, colour, width: int) -> None:
        """A :class:`~beacon_sim.runs.scene.Trail`'s pieces as polylines ``width`` px wide."""
        for piece in trail.pieces():
            pygame.draw.lines(surf, colour, False, view.to_px(piece), width)

    @staticmethod
    def _world_rect(view: View) -> pygame.Rect:
        xmin, ymin, xmax, ymax = view.bounds
        b = view.to_px(np.array([[xmin, ymax], [xmax, ymin]]))
        return pygame.Rect(ipx(b[0, 0]), ipx(b[0, 1]), ipx(b[1, 0] - b[0, 0]), ipx(b[1, 1] - b[0, 1]))

    def _static_layer(self, view: View, world_rect: pygame.Rect) -> pygame.Surface:
        """Background, metric grid, bounds and axis labels: drawn once per view, then blitted."""
        grid = getattr(self.last_world, "grid", None)
        key = (view.key, id(grid), self.show_field)
        if self._static is not None and self._static[0] == key:
            return self._static[1]
        area = pygame.Rect(view.area)
        layer = pygame.Surface(area.size)
        # Draw in window coordinates on a surface offset by the area's corner.
        full = pygame.Surface((area.right, area.bottom))
        full.fill(palette.OUTSIDE)
        full.fill(palette.BACKGROUND, world_rect)
        self._grid(full, view, world_rect)
        if self.show_field:
            map_view.draw_field(full, view, grid)  # the likelihood field, under the walls
        map_view.draw_map(full, view, grid)      # walls (the occupancy grid)
        pygame.draw.rect(full, palette.BOUNDS, world_rect.inflate(4, 4), 3)
        self._axis_labels(full, view, world_rect)
        layer.blit(full, (0, 0), area)
        self._static = (key, layer)
        return layer

    # --- pieces ---------------------------------------------------------------------------
    def _grid(self, surf, view: View, world_rect: pygame.Rect) -> None:
        step = nice_step(view.scale)
        x0, y0, x1, y1 = view.visible_world()
        xmin, ymin, xmax, ymax = view.bounds
        x0, x1 = max(x0, xmin), min(x1, xmax)
        y0, y1 = max(y0, ymin), min(y1, ymax)
        minor = step / 5 if step / 5 * view.scale >= 14 else None
        for spacing, colour, width in ((minor, palette.GRID_MINOR, 1), (step, palette.GRID_MAJOR, 2)):
            if spacing is None:
                continue
            for x in np.arange(math.ceil(x0 / spacing) * spacing, x1 + 1e-9, spacing):
                px = ipx(view.to_px(np.array([x, 0.0]))[0])
                pygame.draw.line(surf, colour, (px, world_rect.top), (px, world_rect.bottom - 1), width)
            for y in np.arange(math.ceil(y0 / spacing) * spacing, y1 + 1e-9, spacing):
                py = ipx(view.to_px(np.array([0.0, y]))[1])
                pygame.draw.line(surf, colour, (world_rect.left, py), (world_rect.right - 1, py), width)

    def _axis_labels(self, surf, view: View, world_rect: pygame.Rect) -> None:
        step = nice_step(view.scale)
        x0, y0, x1, y1 = view.visible_world()
        xmin, ymin, xmax, ymax = view.bounds
        area = pygame.Rect(view.area)
        fmt = (lambda v: f"{v:g}") if step >= 1 else (lambda v: f"{v:.1f}")
        ylab = min(max(world_rect.bottom + 6, area.top + 2), area.bottom - 24)
        self.axis_rects = []  # where the labels are (window px): beacon labels keep off them
        for x in np.arange(math.ceil(max(x0, xmin) / step) * step, min(x1, xmax) + 1e-9, step):
            px = view.to_px(np.array([x, 0.0]))[0]
            t = self.text(fmt(x + 0.0), "small", palette.TEXT_DIM)
            self.axis_rects.append(surf.blit(t, (int(px - t.get_width() / 2), ylab)))
        xlab = max(min(world_rect.left - 6, area.right - 40), area.left + 2)
        for y in np.arange(math.ceil(max(y0, ymin) / step) * step, min(y1, ymax) + 1e-9, step):
            py = view.to_px(np.array([0.0, y]))[1]
            t = self.text(fmt(y + 0.0), "small", palette.TEXT_DIM)
            self.axis_rects.append(
                surf.blit(t, (max(xlab - t.get_width(), area.left + 2), int(py - t.get_height() / 2))))
        unit = self.text(f"grid {step:g} m", "small", palette.TEXT_DIM)
        box = unit.get_rect(topleft=(area.left + 8, area.top + 6))
        surf.fill(palette.OUTSIDE, box.inflate(8, 4))
        surf.blit(unit, box)

    def sensor_discs(self, surf, view: View, sensors, pose) -> None:
        """Each beacon sensor's range (a disc, or a sector for a limited field of view)
        around ``pose``, tinted under the grid, clipped to the world; in a world with walls,
        cut where the walls hide what lies behind (a sensor with ``occluded_by_walls``)."""
        area_clip = surf.get_clip()
        surf.set_clip(self._world_rect(view).clip(area_clip))
        grid = getattr(self.last_world, "grid", None)
        for spec in sensors:
            if not math.isfinite(spec.max_range):
                continue
            walls = grid if getattr(spec, "occluded_by_walls", False) else None
            if walls is not None:
                outline = shapes.sensor_outline(pose, spec.fov, spec.max_range, walls)
            elif spec.fov >= 2 * math.pi:
                outline = circle(pose[:2], spec.max_range, 96)
            else:
                outline = shapes.sector(pose, spec.fov, spec.max_range)
            pts = view.to_px(outline)
            # Tint what is under the disc (multiply blend) so that the grid stays visible.
            box = pygame.Rect(ipx(pts[:, 0].min()) - 2, ipx(pts[:, 1].min()) - 2,
                              ipx(np.ptp(pts[:, 0])) + 5, ipx(np.ptp(pts[:, 1])) + 5)
            box = box.clip(surf.get_clip())
            if box.width > 0 and box.height > 0:
                tint = pygame.Surface(box.size)
                tint.fill((255, 255, 255))
                pygame.draw.polygon(tint, palette.SENSOR_FILL, pts - np.array(box.topleft))
                surf.blit(tint, box, special_flags=pygame.BLEND_RGB_MULT)
            pygame.draw.polygon(surf, palette.SENSOR_EDGE, pts, 2)
        surf.set_clip(area_clip)

    def particles(self, surf: pygame.Surface, view: View, poses: np.ndarray, colour,
                  weights: np.ndarray | None = None) -> None:
        """Each particle as a 3x3 pixel block (2x2 above 20,000 particles), written through a
        pixel array (no draw calls), in the filter's colour darkened to a contrast of 4.5:1
        against the floor (``palette.particle_colours``).

        With ``weights``, particles below half the mean weight (1 / 2N) are drawn in a
        lighter shade (still 3:1) first, so that the ones carrying the belief stand out.
        """
        clip = surf.get_clip()
        poses = np.asarray(poses)
        ax, ay, w, h = view.area
        s = view.scale
        # Pixel coordinates as float32 (to_px in float64 costs more at 100k particles).
        fx = (poses[:, 0] - view.centre[0]).astype(np.float32) * np.float32(s) + np.float32(ax + w / 2)
        fy = (poses[:, 1] - view.centre[1]).astype(np.float32) * np.float32(-s) + np.float32(ay + h / 2)
        ix = fx.astype(np.int32)
        iy = fy.astype(np.int32)
        ok = (ix >= clip.left) & (ix < clip.right - 1) & (iy >= clip.top) & (iy < clip.bottom - 1)
        heavy, pale = palette.particle_colours(colour)  # >= 4.5:1 and 3:1 against the floor
        layers = [(ok, heavy)]
        if weights is not None and len(weights) == len(poses):
            light = np.asarray(weights) < 0.5 / max(len(poses), 1)
            if light.any():
                layers = [(ok & light, pale), (ok & ~light, heavy)]
        # Blocks of 3x3 px up to 20,000 particles (visible on a projector), 2x2 above.
        big = len(poses) <= 20_000
        if big:
            ok &= (ix < clip.right - 2) & (iy < clip.bottom - 2)
            layers = [(m & ok, c) for m, c in layers]
        offsets = [(0, 0), (1, 0), (0, 1), (1, 1)]
        if big:
            offsets += [(2, 0), (2, 1), (0, 2), (1, 2), (2, 2)]
        arr = pygame.surfarray.pixels2d(surf)
        try:
            rows = arr.T  # (height, width): C-ordered when the pitch is 4 px a pixel
            if rows.flags.c_contiguous:  # one index per particle, a constant per offset
                flat, width = rows.reshape(-1), rows.shape[1]
                for mask, col in layers:
                    at = iy[mask].astype(np.intp) * width + ix[mask]
                    value = surf.map_rgb(col)
                    for dx, dy in offsets:
                        flat[at + (dy * width + dx)] = value
            else:
                for mask, col in layers:
                    x, y = ix[mask], iy[mask]
                    value = surf.map_rgb(col)
                    for dx, dy in offsets:
                        arr[x + dx, y + dy] = value
        finally:
            del arr

    def _heat(self, surf, view: View, name: str, bel: GridBelief, colour, tick: int) -> None:
        """The grid belief as a translucent heat map in the filter's colour."""
        key = (tick, view.key, id(bel.prob))
        cached = self._heat_cache.get(name)
        if cached is None or cached[0] != key:
            made = self._make_heat(view, bel, colour)
            if made is None:
                self._heat_cache.pop(name, None)
                return
            cached = (key, *made)
            self._heat_cache[name] = cached
        _, image, at = cached
        surf.blit(image, at)

    @staticmethod
    def _make_heat(view: View, bel: GridBelief, colour):
        prob = np.asarray(bel.prob, dtype=float)
        nx, ny = prob.shape
        ox, oy = bel.origin
        c = bel.cell
        vx0, vy0, vx1, vy1 = view.visible_world()
        i0, i1 = max(math.floor((vx0 - ox) / c), 0), min(math.ceil((vx1 - ox) / c), nx)
        j0, j1 = max(math.floor((vy0 - oy) / c), 0), min(math.ceil((vy1 - oy) / c), ny)
        if i1 <= i0 or j1 <= j0:
            return None
        sub = prob[i0:i1, j0:j1]
        top = float(prob.max())
        if not top > 0:
            return None
        # sqrt: faint mass stays visible. A flat belief is a light tint, a peaked one strong:
        # the peak alpha grows from 60 (uniform, max / mean = 1) towards 200.
        peak = top / max(float(prob.mean()), 1e-300)
        strength = 60.0 + 140.0 * (1.0 - math.exp(-(peak - 1.0) / 3.0))
        alpha = np.sqrt(np.clip(sub / top, 0.0, 1.0)) * strength
        # Crop to the cells that show at all: blitting and scaling cost grows with the area.
        rows = np.flatnonzero(alpha.max(axis=1) >= 1.0)
        cols = np.flatnonzero(alpha.max(axis=0) >= 1.0)
        if not len(rows) or not len(cols):
            return None
        i0, i1 = i0 + rows[0], i0 + rows[-1] + 1
        j0, j1 = j0 + cols[0], j0 + cols[-1] + 1
        alpha = alpha[rows[0]: rows[-1] + 1, cols[0]: cols[-1] + 1]
        small = pygame.Surface((i1 - i0, j1 - j0), pygame.SRCALPHA)
        small.fill((*colour, 0))
        a = pygame.surfarray.pixels_alpha(small)
        a[:] = alpha[:, ::-1].astype(np.uint8)  # screen y down: flip the y index
        del a
        corner = view.to_px(np.array([[ox + i0 * c, oy + j1 * c], [ox + i1 * c, oy + j0 * c]]))
        w = max(ipx(corner[1, 0] - corner[0, 0]), 1)
        h = max(ipx(corner[1, 1] - corner[0, 1]), 1)
        if w * h > 6_000_000:
            return None
        image = pygame.transform.scale(small, (w, h))
        return image, (ipx(corner[0, 0]), ipx(corner[0, 1]))

    def rays(self, surf, view: View, world, pose, readings) -> None:
        """Beacon readings taken at ``pose``: a grey line per beacon seen (to the measured
        range, with a cross at its end; a bearing alone runs to the world's edge)."""
        far = 2.0 * math.hypot(world.width, world.height)
        for m in readings:
            if is_scan(m.kind):    # a laser scan: app/map_view.py
                spec = next((s for s in self.last_world_sensors if s.name == m.sensor), None)
                map_view.draw_scan(surf, view, pose, m, spec.max_range if spec else math.inf,
                                   grid=getattr(world, "grid", None))
                continue
            if m.kind in ("pose", "position", *distance_layer.DISTANCE_KINDS):
                bxy = world.beacon_positions(m.beacon_ids) if len(m.beacon_ids) else np.zeros((0, 2))
                segs = shapes.rays(pose, m, bxy, far)
            else:
                segs = shapes.rays(pose, m, world.beacon_xy, far)
            px = view.to_px(segs)
            for a, b in px:
                pygame.draw.line(surf, palette.RAY, a, b, 2)
            if m.kind == "range_bearing":
                for _, b in px:
                    self._cross(surf, b, 6, palette.RAY, 2)
            elif m.kind in ("pose", "position"):
                self._cross(surf, view.to_px(m.z[0, :2]), 9, palette.RAY, 3)

    def beacons(self, surf, view: View, world, seen, missed=frozenset()) -> None:
        """Every beacon as a square with its ID; those in ``seen`` (IDs) on a green disc, those
        in ``missed`` (in a sensor's range and field of view, not detected) in a dashed
        vermillion ring."""
        pxs = [(ipx(x), ipx(y)) for x, y in view.to_px(world.beacon_xy)]
        half = 9
        squares = [pygame.Rect(x - half, y - half, 2 * half, 2 * half) for x, y in pxs]
        for bcn, (x, y), rect in zip(world.beacons, pxs, squares, strict=True):
            if bcn.id in seen:
                pygame.draw.circle(surf, palette.BEACON_SEEN, (x, y), half + 7)
                pygame.draw.circle(surf, palette.BEACON_SEEN_RING, (x, y), half + 7, 3)
            elif bcn.id in missed:
                ring = circle(np.array([x, y], dtype=float), half + 8, 40)
                polyline(surf, palette.WARN, ring, 3, MISSED_DASH, closed=True)
            pygame.draw.rect(surf, palette.BEACON, rect)
            pygame.draw.rect(surf, palette.BACKGROUND, rect.inflate(-8, -8))
        # Labels: top-right of the beacon unless that hides another beacon or label (real
        # data sets have beacons in close pairs); then the next free corner.
        placed: list[pygame.Rect] = []
        for bcn, (x, y) in zip(world.beacons, pxs, strict=True):
            t = self.text(str(bcn.id), "label", palette.TEXT)
            w, h = t.get_width(), t.get_height()
            corners = [(x + half + 6, y - half - h + 6), (x + half + 6, y + half - 6),
                       (x - half - 6 - w, y - half - h + 6), (x - half - 6 - w, y + half - 6),
                       (x - w // 2, y - half - h - 4), (x - w // 2, y + half + 4),
                       (x + half + 6 + w, y - h // 2), (x - half - 6 - 2 * w, y - h // 2)]
            rects = [pygame.Rect(cx, cy, w, h) for cx, cy in corners]
            at = next((r for r in rects if r.collidelist(placed) < 0 and r.collidelist(squares) < 0
                       and r.inflate(4, 0).collidelist(self.axis_rects) < 0),
                      next((r for r in rects if r.collidelist(placed) < 0
                            and r.collidelist(squares) < 0), rects[0]))
            placed.append(at)
            surf.fill(palette.BACKGROUND, at.inflate(6, -2))
            surf.blit(t, at)
        self.beacon_rects = squares + placed

    @staticmethod
    def _cross(surf, at, r: int, colour, width: int) -> None:
        x, y = ipx(at[0]), ipx(at[1])
        pygame.draw.line(surf, colour, (x - r, y - r), (x + r, y + r), width)
        pygame.draw.line(surf, colour, (x - r, y + r), (x + r, y - r), width)

    def _arrow(self, surf, view: View, mean, colour, radius: float, scale: float = 1.0) -> None:
        """The estimated pose: a filled arrow in the filter's colour, outlined in black."""
        size = max(1.2 * radius, 16.0 / view.scale) * scale
        tri = view.to_px(shapes.arrow(mean, size))
        pygame.draw.polygon(surf, colour, tri)
        pygame.draw.polygon(surf, palette.TEXT, tri, 2)

    def uncertainty(self, surf, view: View, mean, cov, colour, dash, radius: float,
                    width: int | None = None, wedge: bool = True, ellipse: bool = True) -> None:
        """The 95 % ellipse of x-y (``ellipse``) and the +-2 sigma heading wedge (``wedge``),
        in ``dash`` style."""
        lw = width or self.lw
        pts = view.to_px(covariance_ellipse(mean[:2], cov[:2, :2], ELLIPSE_SCALE2, 96))
        if ellipse and np.all(np.isfinite(pts)) and np.ptp(pts[:, 0]) < 1e5 and np.ptp(pts[:, 1]) < 1e5:
            polyline(surf, colour, pts, lw, dash, closed=True)
        if not wedge:
            return
        sigma = math.sqrt(max(float(cov[2, 2]), 0.0))
        r = max(3.2 * radius, 55.0 / view.scale)
        w = view.to_px(shapes.wedge(mean, 2.0 * sigma, r))
        polyline(surf, colour, w, max(lw - 1, 2), dash, closed=True)

    def magnifier(self, surf, view: View, pose, estimates, colours, dashes, radius: float) -> None:
        """A magnified inset (top right of the world) when an estimate's 95 % ellipse is
        smaller than the robot's outline on screen (a converged KF's 2 cm lie inside it):
        the true position (black cross), those estimates (dot) and their ellipses at a
        zoom where the largest is about half the inset, a scale bar, and each ellipse's size
        in words. A frame marks the magnified part around the robot. ``last_magnifier``
        holds what was drawn (for tests): rect, px per metre, {name: ellipse across [px]},
        and the bound's across [px] (``bound_px``) when ``bound_cov`` is shown and small (a
        map world's bound is millimetres)."""
        r_px = max(radius, 14.0 / view.scale) * view.scale
        small = []
        for key, mean, cov in estimates:
            axis = ellipse_diameter(cov)  # the 95 % ellipse's major axis [m]
            if math.isfinite(axis) and axis * view.scale < 2.0 * r_px:
                small.append((key, mean, cov, axis))
        b_axis = ellipse_diameter(self.bound_cov) if self.bound_cov is not None else math.nan
        with_bound = math.isfinite(b_axis) and b_axis * view.scale < 2.0 * r_px
        if not small and not with_bound:
            return
        area = pygame.Rect(view.area)
        font = self.fonts["small"]
        lh = font.get_linesize()
        # wide enough for its words (the bar is at most half the width, its length beside it)
        side = max(min(int(0.3 * min(area.width, area.height)), 360), 150,
                   font.size(MAGNIFIER_HEADING)[0] + 24, 2 * (font.size("50 mm")[0] + 26),
                   max((font.size(f"{key}  99 mm")[0] for key, *_ in small), default=0) + 50,
                   font.size(f"{MAGNIFIER_BOUND}  99 mm")[0] + 50 if with_bound else 0)
        strip_h = lh * (len(small) + with_bound + 3) + 10
        # a corner of the world's area that does not cover the robot (top right first)
        robot_px = view.to_px(np.asarray(pose[:2], dtype=float))
        robot_box = pygame.Rect(ipx(robot_px[0] - r_px) - 8, ipx(robot_px[1] - r_px) - 8,
                                ipx(2 * r_px) + 16, ipx(2 * r_px) + 16)
        blocks = [pygame.Rect(area.right - side - 12, area.top + 12, side, side + strip_h + 2),
                  pygame.Rect(area.right - side - 12, area.bottom - side - strip_h - 14, side,
                              side + strip_h + 2),
                  pygame.Rect(area.left + 12, area.top + 40, side, side + strip_h + 2),
                  pygame.Rect(area.left + 12, area.bottom - side - strip_h - 14, side,
                              side + strip_h + 2)]
        # the corner that hides the least: never the robot, then the fewest beacons and
        # their labels, then the least of the room (the world's bounds) -- the margins first
        room = self._world_rect(view)
        beacons = list(self.beacon_rects)

        def hidden(b: pygame.Rect) -> tuple[bool, int, int]:
            over = b.clip(room)
            return (b.colliderect(robot_box), len(b.collidelistall(beacons)), over.width * over.height)

        block = min(blocks, key=hidden)  # (the first of equals: top right first)
        rect = pygame.Rect(block.left, block.top, side, side)
        # the zoom: the largest small ellipse (or the spread of the means) half the inset
        centre = np.asarray(pose[:2], dtype=float)
        reach = max(max((a for *_, a in small), default=0.0) / 2.0,
                    max((float(np.hypot(*(m[:2] - centre))) for _, m, _, _ in small), default=0.0),
                    b_axis / 2.0 if with_bound else 0.0, 1e-4)
        scale = min(0.25 * side / reach, 1e6)
        if scale < 4.0 * view.scale:  # not worth a magnifier
            return
        sub = View(view.bounds, (rect.left, rect.top, rect.width, rect.height))
        sub.scale, sub.centre = scale, centre
        # where the inset looks, marked on the map
        half = 0.5 * side / scale
        a, b = view.to_px(np.array([[centre[0] - half, centre[1] + half],
                                    [centre[0] + half, centre[1] - half]]))
        mark = pygame.Rect(ipx(a[0]), ipx(a[1]), max(ipx(b[0] - a[0]), 3), max(ipx(b[1] - a[1]), 3))
        pygame.draw.rect(surf, palette.TEXT, mark.inflate(6, 6), 2)
        pygame.draw.line(surf, palette.TEXT_DIM, mark.inflate(6, 6).topright, rect.bottomleft, 1)
        old_clip = surf.get_clip()
        surf.fill(palette.BACKGROUND, rect)
        surf.set_clip(rect)
        step = nice_step(scale, side / 5)
        g0 = np.floor((centre - half) / step) * step
        for k in range(int(2 * half / step) + 2):
            x, y = sub.to_px(g0 + k * step)
            pygame.draw.line(surf, palette.GRID_MINOR, (ipx(x), rect.top), (ipx(x), rect.bottom), 1)
            pygame.draw.line(surf, palette.GRID_MINOR, (rect.left, ipx(y)), (rect.right, ipx(y)), 1)
        c = sub.to_px(centre)
        self._cross(surf, c, 8, palette.ROBOT, 3)
        if with_bound:
            self.bound(surf, sub, pose, self.bound_cov)
        lw = max(self.lw - 1, 2)
        drawn = {}
        for key, mean, cov, axis in sorted(small, key=lambda e: dashes.get(e[0]) is not None):
            m = sub.to_px(mean[:2])
            pygame.draw.circle(surf, colours[key], (ipx(m[0]), ipx(m[1])), lw + 1)
            self.uncertainty(surf, sub, mean, cov, colours[key], dashes.get(key), radius,
                             width=lw, wedge=False)
            drawn[key] = axis * scale
        bound_zoom = None
        if with_bound and b_axis * scale < MIN_BOUND_PX:  # too small at this zoom: a closer look
            bound_zoom = self._bound_inset(surf, sub, rect, pose, b_axis,
                                           [(key, mean) for key, mean, *_ in small], colours)
        surf.set_clip(old_clip)
        pygame.draw.rect(surf, palette.TEXT, rect, 2)
        # the scale bar and the sizes, on a strip along the inset's bottom
        font_key = "small"
        bar_m = nice_step(scale, side / 4)
        bar_px = bar_m * scale
        y = rect.bottom + 6
        strip = pygame.Rect(rect.left, rect.bottom + 2, rect.width, strip_h)
        surf.fill(palette.PANEL, strip)
        pygame.draw.rect(surf, palette.PANEL_EDGE, strip, 1)
        x0 = rect.left + 10
        pygame.draw.line(surf, palette.TEXT, (x0, y + lh // 2), (ipx(x0 + bar_px), y + lh // 2), 4)
        surf.blit(self.text(format_length(bar_m), font_key, palette.TEXT), (ipx(x0 + bar_px) + 8, y))
        y += lh
        surf.blit(self.text(f"zoom x{scale / view.scale:.0f}", font_key, palette.TEXT), (x0, y))
        y += lh
        surf.blit(self.text(MAGNIFIER_HEADING, font_key, palette.TEXT_DIM), (x0, y))
        for key, *_rest, axis in small:
            y += lh
            t = self.text(f"{key}  {format_length(axis)}", font_key, palette.TEXT)
            pygame.draw.line(surf, colours[key], (x0, y + lh // 2), (x0 + 18, y + lh // 2), 5)
            surf.blit(t, (x0 + 26, y))
        if with_bound:
            y += lh
            colour, dash = BOUND_STYLE
            polyline(surf, colour, np.array([[x0, y + lh // 2], [x0 + 18, y + lh // 2]], dtype=float),
                     3, dash)
            surf.blit(self.text(f"{MAGNIFIER_BOUND}  {format_length(b_axis)}", font_key, palette.TEXT),
                      (x0 + 26, y))
        self.last_magnifier = {"rect": rect, "block": rect.union(strip), "scale": scale, "across_px": drawn,
                               "bound_px": b_axis * scale if with_bound else None,
                               "bound_zoom": bound_zoom}

    def _bound_inset(self, surf, sub: View, rect: pygame.Rect, pose, b_axis: float, means,
                     colours) -> float:
        """A second look inside the magnifier (its bottom-left corner) at the bound alone,
        when it is too small at the magnifier's zoom (a map world's millimetres beside a
        filter's centimetres): the true position, the bound's ellipse across 60 % of the box,
        the estimates' means that fall inside. Returns its zoom over the magnifier's."""
        side = max(rect.width * 2 // 5, 100)
        box = pygame.Rect(rect.left + 6, rect.bottom - side - 6, side, side)
        scale = 0.6 * side / max(b_axis, 1e-6)
        view = View(sub.bounds, (box.left, box.top, box.width, box.height))
        view.scale, view.centre = scale, np.asarray(pose[:2], dtype=float)
        clip = surf.get_clip()
        surf.fill(palette.BACKGROUND, box)
        surf.set_clip(box.clip(clip))
        self._cross(surf, view.to_px(view.centre), 4, palette.ROBOT, 2)
        self.bound(surf, view, pose, self.bound_cov)
        for key, mean in means:
            m = view.to_px(np.asarray(mean[:2], dtype=float))
            if box.collidepoint(ipx(m[0]), ipx(m[1])):
                pygame.draw.circle(surf, colours[key], (ipx(m[0]), ipx(m[1])), 4)
        zoom = scale / sub.scale
        surf.blit(self.text(f"x{zoom:.0f} more", "small", palette.TEXT_DIM), (box.left + 4, box.top + 2))
        surf.set_clip(clip)
        pygame.draw.rect(surf, palette.TEXT, box, 1)
        return zoom

    def priors(self, surf, view: View, steps: dict, colours, used_ids: set[int]) -> None:
        """The step view: for each filter the 95 % ellipse after predict (the prior, dashed,
        thinner) and a line from the prior's mean to the posterior's (what the update
        moved), and a black ring around each beacon the update used. The posterior itself is
        drawn solid by the normal pass, over this."""
        lw = max(self.lw - 1, 2)
        for name, ((m0, c0), (m1, _)) in steps.items():
            colour = colours[name]
            pts = view.to_px(covariance_ellipse(m0[:2], c0[:2, :2], ELLIPSE_SCALE2, 96))
            if np.all(np.isfinite(pts)) and np.ptp(pts[:, 0]) < 1e5 and np.ptp(pts[:, 1]) < 1e5:
                polyline(surf, colour, pts, lw, PRIOR_DASH, closed=True)
            a, b = view.to_px(np.array([m0[:2], m1[:2]]))
            pygame.draw.line(surf, colour, a, b, 2)
            pygame.draw.circle(surf, colour, (ipx(a[0]), ipx(a[1])), 6, 2)
        world = self.last_world
        if world is not None and used_ids:
            for bcn, (x, y) in zip(world.beacons, view.to_px(world.beacon_xy), strict=True):
                if bcn.id in used_ids:
                    pygame.draw.circle(surf, palette.TEXT, (ipx(x), ipx(y)), 24, 4)

    def bound(self, surf, view: View, pose, P) -> None:
        """The best achievable 95 % ellipse (the PCRB ``P`` (3, 3)) around the TRUE pose,
        black and dotted: no unbiased filter's ellipse can be smaller."""
        colour, dash = BOUND_STYLE
        pts = view.to_px(covariance_ellipse(np.asarray(pose)[:2], np.asarray(P)[:2, :2],
                                            ELLIPSE_SCALE2, 96))
        if np.all(np.isfinite(pts)) and np.ptp(pts[:, 0]) < 1e5 and np.ptp(pts[:, 1]) < 1e5:
            polyline(surf, colour, pts, max(self.lw - 1, 2), dash, closed=True)

    def robot(self, surf, view: View, pose, radius: float) -> None:
        """The true robot as an OUTLINE (black chassis edge, grey wheels, heading mark): it is
        drawn under the beliefs and never covers an estimate or a small ellipse."""
        r = max(radius, 14.0 / view.scale)
        lw = max(self.lw - 1, 2)
        body, wheels = shapes.chassis(pose, r)
        for wheel in wheels:
            pygame.draw.polygon(surf, palette.ROBOT_WHEEL, view.to_px(wheel), 2)
        pygame.draw.polygon(surf, palette.ROBOT, view.to_px(body), lw)
        a, b = view.to_px(shapes.heading_mark(pose, r))
        pygame.draw.line(surf, palette.ROBOT, a, b, lw)

    def _drag_ghost(self, surf, view: View, drag, pose, radius: float) -> None:
        start, now = (np.asarray(p, dtype=float) for p in drag)
        xy = view.to_world(start)
        d = now - start
        theta = math.atan2(-d[1], d[0]) if math.hypot(*d) > 8 else float(pose[2])
        ghost = np.array([xy[0], xy[1], theta])
        body, _ = shapes.chassis(ghost, max(radius, 14.0 / view.scale))
        pygame.draw.polygon(surf, palette.WARN, view.to_px(body), 3)
        if math.hypot(*d) > 8:
            pygame.draw.line(surf, palette.WARN, start, now, 3)
