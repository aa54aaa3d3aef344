"""The world's picture, layer by layer: ``WorldRenderer`` puts together the layers, each in its
own module, in the order that keeps every estimate visible (floor, sensor discs and heat maps,
trails, readings, beacons and the true robot, particles, estimates, magnifier).

The layers and what they stand on, one way only::

    render (WorldRenderer, ShowOptions)
      -> magnifier -> estimate_layer -> canvas
      -> floor_layer, sensing_layer, beacon_layer, robot_layer, particle_layer, heat_layer -> canvas
      -> association_layer, distance_layer, map_layer, map_view (their own layers)
    every layer -> strokes (lines in pixels) -> view (metres to pixels), palette, shapes

All geometry arrives in metres from the core (``geometry``) or ``shapes``; the layers only
convert to pixels and draw. The screen's y axis points down; the world's points up.
"""

from __future__ import annotations

from dataclasses import dataclass

import pygame

from beacon_sim.app import association_layer, distance_layer, palette
from beacon_sim.app.beacon_layer import BeaconLayer
from beacon_sim.app.floor_layer import FloorLayer
from beacon_sim.app.heat_layer import HeatLayer
from beacon_sim.app.in_view import missed_ids, sensors_read
from beacon_sim.app.magnifier import Magnifier
from beacon_sim.app.map_layer import MapLayer
from beacon_sim.app.particle_layer import ParticleLayer
from beacon_sim.app.robot_layer import RobotLayer
from beacon_sim.app.sensing_layer import SensingLayer
from beacon_sim.app.strokes import line_width, notched_joints, polyline
from beacon_sim.app.view import View, world_rect
from beacon_sim.filters.base import GridBelief, ParticleBelief
from beacon_sim.runs.scene import Scene


@dataclass
class ShowOptions:
    """Which layers the window shows; each is switched by a key (``controls``)."""

    particles: bool = True
    trails: bool = True
    ellipses: bool = True
    chart: bool = False  # the strip chart of error and 2-sigma (C)
    step: bool = True  # while paused: the last tick's prior and posterior (V)
    bound: bool = False  # the best achievable covariance, the PCRB (B)
    field: bool = False  # a map world's likelihood field under the walls (L)
    hdop: bool = False  # distance beacons: the floor shaded by the layout's HDOP (O)


#: The most steps of :meth:`WorldRenderer.phases` (the yields plus the last part): five for
#: one robot, four plus one per robot (up to four) for a team.
PHASES = 8


#: A team's estimate arrows at this fraction of a single robot's: a few filters' arrows on
#: one robot leave its outline visible.
TEAM_ARROW_SCALE = 0.65


class WorldRenderer(FloorLayer, SensingLayer, BeaconLayer, RobotLayer, ParticleLayer, HeatLayer,
                    Magnifier):
    """Draws one frame of the world into a surface (the HUD is drawn by ``hud``): the layers
    it is made of, in order."""

    def __init__(self, fonts: dict[str, pygame.font.Font]):
        super().__init__(fonts)
        self.map_layer = MapLayer()  # SLAM filters' estimated maps (app/map_layer.py)
        self.hdop_layer = distance_layer.HdopShading()  # distance beacons' HDOP floor (O)

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
        """:meth:`draw` as a generator of five steps, in the order of :meth:`draw`: each
        ``next`` draws one more layer (the floor and the heat maps, the trails, rays,
        beacons and the true robot, the particles, ``extra`` and the estimates, the
        magnifier), all from the same session state (the window spreads them over two or
        three frames). The clip is restored when it ends or is closed half way. A team's
        world (:meth:`team_phases`) takes up to :data:`PHASES` steps."""
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
                                     world_rect(view).clip(surf.get_clip()))
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
                self.hdop_layer.key_box(surf, world_rect(view).clip(surf.get_clip()),
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
        """:meth:`draw_team` as a generator of :data:`PHASES` steps (see :meth:`phases`)."""
        self.last_world = session.team.world
        self.show_field = show.field
        dashes = dashes or {}
        old_clip = self.begin(surf, view)
        try:
            yield from self._team_layers(surf, view, session, colours, show, drag, dashes, extra)
        finally:
            surf.set_clip(old_clip)

    def _team_layers(self, surf, view, session, colours, show, drag, dashes, extra):
        """:meth:`team_phases`' layers, inside the clip, in at most :data:`PHASES` steps: the
        floor and the sensor discs; the trails; the readings and the robots; the beliefs, a
        step per robot (up to four); the rings and the tags."""
        team = session.team
        poses = session.poses
        radii = [r.scenario.robot_radius for r in team.robots]
        for r, pose in zip(team.robots, poses, strict=True):
            self.sensor_discs(surf, view, r.scenario.sensors, pose)
        yield
        shown = [n for n in session.names if session.visible[n] and not session.status[n].failed]
        if show.trails:
            for trail in session.truth_trails:
                self.trail(surf, view, trail, palette.TRUTH_TRAIL, 5)
            for name in shown:
                for trail in session.trails[name]:
                    self.trail(surf, view, trail, colours[name], 2)
        yield
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
        n, k = len(radii), min(len(radii), PHASES - 4)
        for j in range(k):
            for i in range(j * n // k, (j + 1) * n // k):  # a step per robot (or a few robots)
                ests = [(name, est[0][i], est[1][i]) for name, est in beliefs.items() if est is not None]
                # smaller arrows than alone and no heading wedges: a dozen beliefs on three robots
                self.estimates(surf, view, ests, colours, dashes, radii[i], show.ellipses,
                               TEAM_ARROW_SCALE, wedges=False)
            yield
        self.tags: list[pygame.Rect] = []
        for i, (r, pose) in enumerate(zip(team.robots, poses, strict=True)):
            self.robot_ring(surf, view, pose, radii[i])
            self.name_tag(surf, view, pose, radii[i], r.name, i == session.driven)
        if drag is not None:
            self._drag_ghost(surf, view, drag, session.true_pose, radii[session.driven])

    def begin(self, surf: pygame.Surface, view: View) -> pygame.Rect:
        """Start a frame of the world: the line width for the window's height, the static
        layer (background, grid, bounds, labels), the clip set to the view's area. Returns
        the clip to restore when done."""
        self.lw = line_width(surf.get_height())
        area = pygame.Rect(view.area)
        old_clip = surf.get_clip()
        surf.set_clip(area)
        surf.blit(self._static_layer(view, world_rect(view)), area)
        return old_clip

    def trail(self, surf, view: View, trail, colour, width: int) -> None:
        """A :class:`~beacon_sim.runs.scene.Trail`'s pieces as polylines ``width`` px wide."""
        for piece in trail.pieces():
            pygame.draw.lines(surf, colour, False, view.to_px(piece), width)


# View, polyline and notched_joints stay importable from here: gym.py and the docs name them.
__all__ = ["PHASES", "ShowOptions", "View", "WorldRenderer", "notched_joints", "polyline"]
