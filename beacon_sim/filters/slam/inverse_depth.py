"""Inverse-depth landmarks for bearing-only SLAM in the plane (Civera, Davison and Montiel,
"Inverse depth parametrization for monocular SLAM", IEEE T-RO 2008; docs/slam.md).

One bearing says where a landmark's ray is, not how far along it the landmark stands. In
inverse depth the landmark is ``y = (x0, y0, theta, rho)``: the robot's position when it
first saw it (x0, y0) [m], the ray's direction in the world theta [rad], and the inverse of
the depth along the ray rho [1/m], so the point is ``(x0, y0) + (cos theta, sin theta) / rho``.
Depths from a metre to infinity (rho = 0) are then one Gaussian in rho, and the bearing is
close to linear in rho, so the landmark can enter the EKF at its first bearing and every
later one is used (unlike delayed initialisation, which waits for parallax). Once the depth
is well known the landmark is converted to a plain ``(x, y)`` (half the state, a model as
linear). Frames and units as everywhere: world frame, metres, radians, y up.
"""

from __future__ import annotations

import math

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.measurement_models import relative_bearing_scalar


def initialise(pose: np.ndarray, b: float, rho0: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The landmark ``(x, y, theta + b, rho0)`` a bearing b [rad] from pose (3,) starts.

    Returns
    -------
    y : ndarray, shape (4,)
    Gx : ndarray, shape (4, 3)   d y / d(x, y, theta)
    Gz : ndarray, shape (4,)     d y / d b
    """
    pose = np.asarray(pose, dtype=float).reshape(3)
    y = np.array([pose[0], pose[1], wrap(pose[2] + b), rho0])
    Gx = np.zeros((4, 3))
    Gx[0, 0] = Gx[1, 1] = Gx[2, 2] = 1.0
    Gz = np.array([0.0, 0.0, 1.0, 0.0])
    return y, Gx, Gz


def observe(pose: np.ndarray, y: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Expected bearing [rad] of inverse-depth landmark y (4,) from pose (3,), and its
    Jacobians in the pose (3,) and in y (4,).

    With ``h = rho ((x0, y0) - (x, y)) + (cos theta, sin theta)`` (the direction to the
    landmark scaled by rho > 0, defined at rho = 0 too), the bearing is
    ``atan2(h_y, h_x) - theta_robot``; ``d atan2 / d h = (-h_y, h_x) / |h|^2`` and::

        dh/d(x, y) = -rho I     dh/d(x0, y0) = rho I
        dh/d theta = (-sin theta, cos theta)     dh/d rho = (x0 - x, y0 - y)
    """
    pose = np.asarray(pose, dtype=float).reshape(3)
    x0, y0, th, rho = (float(v) for v in np.asarray(y, dtype=float).reshape(4))
    ex, ey = x0 - pose[0], y0 - pose[1]
    c, s = math.cos(th), math.sin(th)
    hx, hy = rho * ex + c, rho * ey + s
    q = hx * hx + hy * hy
    ga = np.array([-hy / q, hx / q])                  # d bearing / d h
    zhat = wrap(relative_bearing_scalar(hx, hy, float(pose[2])))  # h is the direction to it
    Hx = np.array([-rho * ga[0], -rho * ga[1], -1.0])
    Hy = np.array([rho * ga[0], rho * ga[1], ga @ np.array([-s, c]), ga @ np.array([ex, ey])])
    return float(zhat), Hx, Hy


def to_xy(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The Euclidean point (2,) of y (4,) (rho must not be 0) and its Jacobian (2, 4)::

        m = (x0 + cos theta / rho, y0 + sin theta / rho)
        dm/d(x0, y0, theta, rho) = [[1, 0, -sin theta / rho, -cos theta / rho^2],
                                    [0, 1,  cos theta / rho, -sin theta / rho^2]]
    """
    x0, y0, th, rho = (float(v) for v in np.asarray(y, dtype=float).reshape(4))
    c, s = math.cos(th), math.sin(th)
    m = np.array([x0 + c / rho, y0 + s / rho])
    J = np.array([[1.0, 0.0, -s / rho, -c / rho ** 2],
                  [0.0, 1.0, c / rho, -s / rho ** 2]])
    return m, J


def linearity_index(y: np.ndarray, var_rho: float, position: np.ndarray) -> float:
    """Civera et al.'s linearity index of the conversion to Euclidean, seen from ``position``
    (2,) [m]: ``L = 4 sigma_d |cos alpha| / d1`` with ``sigma_d = sigma_rho / rho^2`` the
    depth's standard deviation, ``d1`` the distance from here to the point and alpha the
    angle between the landmark's ray and the line of sight from here. Small (they use 0.1):
    the point is as good as Euclidean. ``inf`` while rho <= 0 (at or beyond infinity)."""
    x0, y0, th, rho = (float(v) for v in np.asarray(y, dtype=float).reshape(4))
    if not rho > 0.0 or not var_rho >= 0.0:
        return math.inf
    m = np.array([x0 + math.cos(th) / rho, y0 + math.sin(th) / rho])
    los = m - np.asarray(position, dtype=float).reshape(2)
    d1 = float(np.hypot(*los))
    if d1 == 0.0:
        return math.inf
    cos_a = float(los @ np.array([math.cos(th), math.sin(th)])) / d1
    return 4.0 * math.sqrt(var_rho) / rho ** 2 * abs(cos_a) / d1
