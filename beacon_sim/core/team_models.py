"""Robot-to-robot readings: the expected measurement of robot j seen from robot i, and its
Jacobians with respect to both poses.

Poses are ``[x, y, theta]`` [m, m, rad] in the world frame. The observer i measures the
range [m] to the subject j and the bearing [rad] to it relative to i's heading::

    dx = x_j - x_i,  dy = y_j - y_i,  q = dx^2 + dy^2,  r = sqrt(q)
    h(x_i, x_j) = [r, atan2(dy, dx) - theta_i]                   (bearing wrapped)

    dh/dx_i = [[-dx/r, -dy/r,  0],      dh/dx_j = [[ dx/r,  dy/r, 0],
               [ dy/q, -dx/q, -1]]                 [-dy/q,  dx/q, 0]]

A bearing-only robot sensor uses the second row alone. The same rows as a beacon reading
(core/measurement_models.py) with the beacon replaced by a second uncertain pose.
"""

from __future__ import annotations

import math

import numpy as np

from beacon_sim.core import portable_math as pm
from beacon_sim.core.angles import wrap
from beacon_sim.core.measurement_models import relative_bearing_scalar

#: Robot-sensor measurement kinds and the width of one row of ``Measurement.z``. The IDs a
#: reading names (``Measurement.beacon_ids``) are then the IDs of the robots seen.
ROBOT_MEASUREMENT_DIMS = {"robot_bearing": 1, "robot_range_bearing": 2}


def relative_range_bearing(pose_i, pose_j) -> np.ndarray:
    """``[range, bearing]`` of robot j seen from robot i, shape (2,) [m, rad] (portable maths:
    the team simulation's readings are these)."""
    dx = float(pose_j[0]) - float(pose_i[0])
    dy = float(pose_j[1]) - float(pose_i[1])
    bearing = relative_bearing_scalar(dx, dy, float(pose_i[2]), portable=True)
    return np.array([pm.hypot1(dx, dy), wrap(bearing)])


def relative_range_bearing_jacobians(pose_i, pose_j) -> tuple[np.ndarray, np.ndarray]:
    """``(dh/dx_i, dh/dx_j)``, each of shape (2, 3), of :func:`relative_range_bearing`."""
    dx = float(pose_j[0]) - float(pose_i[0])
    dy = float(pose_j[1]) - float(pose_i[1])
    q = dx * dx + dy * dy
    r = math.sqrt(q)
    hj = np.array([[dx / r, dy / r, 0.0], [-dy / q, dx / q, 0.0]])
    hi = -hj
    hi[1, 2] = -1.0
    return hi, hj


def relative_rows(kind: str, pose_i, pose_j) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(h, H_i, H_j)`` for a robot-sensor ``kind``: h shape (d,), H_i and H_j shape (d, 3)."""
    h = relative_range_bearing(pose_i, pose_j)
    hi, hj = relative_range_bearing_jacobians(pose_i, pose_j)
    if kind == "robot_bearing":
        return h[1:], hi[1:], hj[1:]
    if kind == "robot_range_bearing":
        return h, hi, hj
    raise ValueError(f"not a robot-sensor kind: {kind!r}")


def teammate_position(pose_i, z) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Robot j's position [m] from observer i's pose and a range-bearing reading ``z`` =
    ``[r, b]`` of j, with the Jacobians with respect to the pose (2, 3) and to z (2, 2)::

        phi = theta_i + b,   p_j = p_i + r [cos phi, sin phi]

    (what an observer sends its teammate in covariance-intersection cooperative
    localization, Carrillo-Arce et al. 2013).
    """
    r, b = float(z[0]), float(z[1])
    phi = float(pose_i[2]) + b
    c, s = math.cos(phi), math.sin(phi)
    p = np.array([float(pose_i[0]) + r * c, float(pose_i[1]) + r * s])
    j_pose = np.array([[1.0, 0.0, -r * s], [0.0, 1.0, r * c]])
    j_z = np.array([[c, -r * s], [s, r * c]])
    return p, j_pose, j_z
