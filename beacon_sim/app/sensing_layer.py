"""What the sensors reach and read, in the world: each beacon sensor's range (a disc, a
sector, cut by walls), a ray per beacon reading (a laser scan through ``map_view``), and the
robot-to-robot readings of a team.
"""

from __future__ import annotations

import math

import numpy as np
import pygame

from beacon_sim.app import ahead, distance_layer, map_view, palette, shapes
from beacon_sim.app.canvas import Canvas
from beacon_sim.app.strokes import draw_cross, polyline
from beacon_sim.app.view import View, ipx, world_rect
from beacon_sim.core.sensor_kinds import is_scan


class SensingLayer(Canvas):
    """Sensor discs and reading rays."""

    def sensor_discs(self, surf, view: View, sensors, pose) -> None:
        """Each beacon sensor's range (a disc, or a sector for a limited field of view)
        around ``pose``, tinted under the grid, clipped to the world; in a world with walls,
        cut where the walls hide what lies behind (a sensor with ``occluded_by_walls``).
        A whole disc is drawn on the whole pixel nearest its centre, with its radius
        rounded to a pixel, from a tint kept per radius (:meth:`disc_tint`)."""
        area_clip = surf.get_clip()
        surf.set_clip(world_rect(view).clip(area_clip))
        grid = getattr(self.last_world, "grid", None)
        for spec in sensors:
            if not math.isfinite(spec.max_range):
                continue
            walls = grid if getattr(spec, "occluded_by_walls", False) else None
            if walls is None and spec.fov >= 2 * math.pi:
                c = view.to_px(np.asarray(pose, dtype=float)[:2])
                r = spec.max_range * view.scale
                if np.all(np.isfinite(c)) and 0.0 < r < 1e5:
                    cx, cy, rp = ipx(c[0]), ipx(c[1]), max(ipx(r), 1)
                    surf.blit(self.disc_tint(rp), (cx - rp - 1, cy - rp - 1),
                              special_flags=pygame.BLEND_RGB_MULT)
                    pygame.draw.circle(surf, palette.SENSOR_EDGE, (cx, cy), rp, 2)
                continue
            if walls is not None:  # (computed ahead on the filters' worker: ahead.py)
                outline = ahead.sensor_outline(pose, spec, walls)
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

    def disc_tint(self, radius: int) -> pygame.Surface:
        """A (2 r + 3) px square, white but for a disc of ``radius`` px in the sensor's tint
        at its centre: multiplied onto the world (kept per radius: a frame draws a robot's
        disc anew wherever the robot is; a few radii, a window's sensors at its zoom)."""
        tints = self.__dict__.setdefault("_disc_tints", {})
        tint = tints.get(radius)
        if tint is None:
            if len(tints) >= 8:
                tints.clear()
            tint = tints[radius] = pygame.Surface((2 * radius + 3, 2 * radius + 3))
            tint.fill((255, 255, 255))
            pygame.draw.circle(tint, palette.SENSOR_FILL, (radius + 1, radius + 1), radius)
        return tint

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
                    draw_cross(surf, b, 6, palette.RAY, 2)
            elif m.kind in ("pose", "position"):
                draw_cross(surf, view.to_px(m.z[0, :2]), 9, palette.RAY, 3)

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
