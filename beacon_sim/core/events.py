"""Scheduled events: kidnapping, sensor blackouts and bursts of motion noise.

Events are scheduled in seconds and fire on the first tick whose time is at or after
their ``time``. The filters are never told about them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.world import World


def first_tick_at(time: float, dt: float) -> int:
    """The first tick ``k >= 1`` with ``k * dt >= time`` (a tolerance absorbs rounding)."""
    return max(1, math.ceil(time / dt - 1e-9))


@dataclass(frozen=True)
class Kidnap:
    """Teleport the robot at ``time`` [s].

    Exactly one of: ``pose`` (absolute ``[x, y, theta]``), ``offset`` (world-frame
    displacement ``[dx, dy, dtheta]``, e.g. seed 000's ``[1, 0.5, -pi/2]``) or
    ``random`` (a uniform pose in the world bounds, from the events stream).
    """

    time: float
    pose: tuple[float, float, float] | None = None
    offset: tuple[float, float, float] | None = None
    random: bool = False

    kind = "kidnap"

    def target(self, current: np.ndarray, world: World, rng: np.random.Generator) -> np.ndarray:
        """Where the robot lands, given its current true pose."""
        if self.pose is not None:
            out = np.array(self.pose, dtype=float)
        elif self.offset is not None:
            out = np.asarray(current, dtype=float) + np.array(self.offset, dtype=float)
        else:
            out = world.random_pose(rng, margin=0.05 * min(world.width, world.height))
        out[2] = wrap(out[2])
        return world.clip(out)


@dataclass(frozen=True)
class Blackout:
    """Sensors listed in ``sensors`` (all when empty) are silent for ``duration`` [s]."""

    time: float
    duration: float
    sensors: tuple[str, ...] = ()

    kind = "blackout"

    def covers(self, sensor: str) -> bool:
        return not self.sensors or sensor in self.sensors


@dataclass(frozen=True)
class NoiseBurst:
    """Extra noise on the executed command for ``duration`` [s] (seed 002's impulsive noise).

    ``v_std`` [m/s] and ``omega_std`` [rad/s] add (in quadrature) to the motion noise.
    """

    time: float
    duration: float
    v_std: float = 0.0
    omega_std: float = 0.0

    kind = "noise_burst"


Event = Kidnap | Blackout | NoiseBurst


def active_ticks(event: Blackout | NoiseBurst, dt: float) -> range:
    """Ticks during which an interval event is in force: ``[time, time + duration)``."""
    start = first_tick_at(event.time, dt)
    stop = first_tick_at(event.time + event.duration, dt)
    return range(start, max(stop, start + 1) if event.duration > 0 else start)
