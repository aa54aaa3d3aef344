"""The true robots: the outline drawn under every belief, and for a team the driven robot's
halo, a ring around each robot over the beliefs and its name tag; the ghost of a click-kidnap
being dragged.
"""

from __future__ import annotations

import math

import numpy as np
import pygame

from beacon_sim.app import palette, shapes
from beacon_sim.app.canvas import Canvas
from beacon_sim.app.view import View, ipx


class RobotLayer(Canvas):
    """The true robots (outline, halo, ring, tag) and the kidnap drag's ghost."""

    #: A team frame's name tags drawn so far (``render`` starts the list each team frame).
    tags: list[pygame.Rect]

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
