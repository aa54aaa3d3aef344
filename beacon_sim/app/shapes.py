"""Outlines in metres (world frame) for what the window draws beyond the core's ellipses
and circles: the robot's chassis, a heading wedge, an estimate arrow, measurement rays.

Pure numpy; ``render`` converts the results to pixels.
"""

from __future__ import annotations

import math

import numpy as np

from beacon_sim.core.raycast import cast_rays
from beacon_sim.core.types import Measurement


def _place(local: np.ndarray, pose) -> np.ndarray:
    """Rotate body-frame points (k, 2) by the heading and move them to the pose's position."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    rot = np.array([[c, -s], [s, c]])
    return local @ rot.T + np.asarray(pose[:2], dtype=float)


def chassis(pose, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """A differential-drive robot of ``radius`` [m]: body outline (k, 2) and the two
    wheels as one array (2, 4, 2), world frame [m]."""
    r = radius
    body = np.array([[1.0, 0.0], [0.55, 0.75], [-0.8, 0.75], [-0.8, -0.75], [0.55, -0.75]]) * r
    wheel = np.array([[-0.35, 0.0], [0.35, 0.0], [0.35, 0.22], [-0.35, 0.22]]) * r
    left = wheel + np.array([0.0, 0.78 * r])
    right = wheel * np.array([1.0, -1.0]) + np.array([0.0, -0.78 * r])
    return _place(body, pose), np.stack([_place(left, pose), _place(right, pose)])


def heading_mark(pose, radius: float) -> np.ndarray:
    """A short segment (2, 2) from the centre towards the front [m]."""
    return _place(np.array([[0.0, 0.0], [0.85 * radius, 0.0]]), pose)


def arrow(pose, length: float) -> np.ndarray:
    """A pointed marker for an estimated pose: a triangle (4, 2) [m] pointing along theta."""
    L = length
    local = np.array([[L, 0.0], [-0.6 * L, 0.55 * L], [-0.3 * L, 0.0], [-0.6 * L, -0.55 * L]])
    return _place(local, pose)


def wedge(pose, half_angle: float, radius: float, n: int = 24) -> np.ndarray:
    """The sector ``theta +- half_angle`` [rad] of ``radius`` [m] at the pose's position,
    outline (n + 2, 2) [m] starting and ending at the centre. A half angle >= pi gives a
    full circle (no centre points)."""
    xy = np.asarray(pose[:2], dtype=float)
    if half_angle >= math.pi:
        t = np.linspace(-math.pi, math.pi, 2 * n, endpoint=False)
        return xy + radius * np.stack([np.cos(t), np.sin(t)], 1)
    t = pose[2] + np.linspace(-half_angle, half_angle, n)
    arc = xy + radius * np.stack([np.cos(t), np.sin(t)], 1)
    return np.vstack([xy, arc, xy])


def sensor_outline(pose, fov: float, radius: float, grid=None, n: int = 240) -> np.ndarray:
    """What a sensor of field of view ``fov`` [rad] and range ``radius`` [m] at ``pose`` can
    reach, as a closed outline [m]: its disc (or sector), cut where a ray from the pose meets
    a wall of the occupancy grid ``grid`` (beacons behind a wall are not seen; None: no walls).
    ``n`` rays over the field of view (240: about one every 1.5 degrees)."""
    xy = np.asarray(pose[:2], dtype=float)
    full = fov >= 2.0 * math.pi
    if full:
        t = pose[2] + np.linspace(-math.pi, math.pi, n, endpoint=False)
    else:
        t = pose[2] + np.linspace(-0.5 * fov, 0.5 * fov, max(n * fov / (2.0 * math.pi), 8.0).__ceil__())
    r = cast_rays(grid, xy, t, radius) if grid is not None else np.full(t.shape, float(radius))
    arc = xy + r[:, None] * np.stack([np.cos(t), np.sin(t)], 1)
    return arc if full else np.vstack([xy, arc, xy])


def sector(pose, fov: float, radius: float, n: int = 48) -> np.ndarray:
    """Field of view ``fov`` [rad] (full angle) out to ``radius`` [m], as a closed outline."""
    return wedge(pose, 0.5 * fov, radius, n)


def rays(pose, m: Measurement, beacon_xy: np.ndarray, far: float) -> np.ndarray:
    """Segments (k, 2, 2) [m] from the pose for one reading.

    bearing: along the measured bearing, ``far`` metres long (no range is measured);
    range_bearing: along the bearing, as long as the measured range;
    pose / position fixes: to each beacon the fix was computed from (``beacon_xy`` rows).
    """
    p = np.asarray(pose[:2], dtype=float)
    z = np.asarray(m.z, dtype=float)
    if m.kind in ("bearing", "range_bearing"):
        b = pose[2] + z[:, -1]
        r = np.full(len(z), far) if m.kind == "bearing" else z[:, 0]
        end = p + np.stack([r * np.cos(b), r * np.sin(b)], 1)
    else:
        end = np.asarray(beacon_xy, dtype=float).reshape(-1, 2)
    start = np.broadcast_to(p, end.shape)
    return np.stack([start, end], 1)


def robot_rays(pose, m: Measurement, seen_xy: np.ndarray) -> np.ndarray:
    """Segments (k, 2, 2) [m] from an observer's pose for one robot reading:
    along the measured bearing, as long as the measured range (``robot_range_bearing``) or,
    for a bearing alone (``robot_bearing``), as far as the seen robot (``seen_xy`` (k, 2),
    its true position: the reading itself gives no length)."""
    p = np.asarray(pose[:2], dtype=float)
    z = np.asarray(m.z, dtype=float)
    b = pose[2] + z[:, -1]
    if m.kind == "robot_range_bearing":
        r = z[:, 0]
    else:
        r = np.hypot(*(np.asarray(seen_xy, dtype=float).reshape(-1, 2) - p).T)
    end = p + np.stack([r * np.cos(b), r * np.sin(b)], 1)
    return np.stack([np.broadcast_to(p, end.shape), end], 1)
