"""Builders shared by the Gaussian filter tests: contexts and measurements by hand."""

from __future__ import annotations

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.motion import MotionNoise
from beacon_sim.core.sensors import SensorNoise, SensorSpec
from beacon_sim.core.types import Beacon, Measurement
from beacon_sim.core.world import World
from beacon_sim.filters.base import FilterContext, GaussianBelief

SENSORS = (
    SensorSpec("brg", "bearing", noise=SensorNoise(bearing_std=0.05)),
    SensorSpec("rb", "range_bearing", noise=SensorNoise(range_std=0.1, bearing_std=0.05)),
    SensorSpec("pose", "pose", noise=SensorNoise(position_std=0.1, heading_std=0.05)),
    SensorSpec("pos", "position", noise=SensorNoise(position_std=0.02)),
)
BEACONS = ((1, 2.0, 2.0), (2, 8.0, 2.0), (3, 8.0, 8.0), (4, 2.0, 8.0), (5, -5.0, 0.001))
NOISE = MotionNoise(v_std=0.02, v_frac=0.05, omega_std=0.02, omega_frac=0.05, pose_std=(0.001, 0.002, 0.001))


def context(params=None, beacons=BEACONS, noise=NOISE, sensors=SENSORS, dt=0.1) -> FilterContext:
    world = World((-10.0, -10.0, 10.0, 10.0), tuple(Beacon(i, x, y) for i, x, y in beacons))
    return FilterContext("test", world, dt, noise, sensors, dict(params or {}),
                         np.random.default_rng(0))


def belief(mean, std) -> GaussianBelief:
    return GaussianBelief(np.array(mean, dtype=float), np.diag(np.square(std)))


def bearing(z, ids, sensor="brg") -> Measurement:
    return Measurement(sensor, "bearing", np.array(z, dtype=float).reshape(-1, 1), np.array(ids))


def range_bearing(z, ids, sensor="rb") -> Measurement:
    return Measurement(sensor, "range_bearing", np.array(z, dtype=float).reshape(-1, 2), np.array(ids))


def pose_fix(z, n_beacons=1) -> Measurement:
    return Measurement("pose", "pose", np.array(z, dtype=float).reshape(1, 3), np.arange(n_beacons))


def position_fix(z, hdop=1.5) -> Measurement:
    return Measurement("pos", "position", np.array(z, dtype=float).reshape(1, 2), np.arange(3),
                       hdop=hdop)


def textbook_update(mean, P, z, h, H, R, angle_rows):
    """The stacked EKF/KF update written from the equations with matrix inverses:
    y = wrap(z - h), S = H P H^T + R, K = P H^T S^-1, Joseph covariance."""
    y = np.asarray(z, dtype=float) - h
    for i in angle_rows:
        y[i] = wrap(y[i])
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    m = mean + K @ y
    m[2] = wrap(m[2])
    A = np.eye(3) - K @ H
    return m, A @ P @ A.T + K @ R @ K.T
