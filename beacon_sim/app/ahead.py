"""What the window computes for a tick that costs, done ahead on the filters' worker thread
(``runs/filter_worker``) as soon as the tick is fed, off the thread that draws: the live
bound (:class:`TickBound`, read as of the tick shown) and, for the drawing
(:class:`DrawingAhead`), the sensor discs cut by walls, the walls on a scan's beams, the
curves and the fix of a TDOA reading.

Each drawing piece is a pure function of numbers the tick carries, kept by those numbers (a
few dozen at most): the drawing asks for it by the same numbers (:func:`sensor_outline`,
:func:`scan_walls`, :func:`tdoa_fix`) and finds it ready, or computes it itself (no worker,
a reading older than the pose it is drawn from): the same function on the same numbers, so
the same pixels. Without a worker nothing is computed ahead.
"""

from __future__ import annotations

import math

import numpy as np

from beacon_sim.app import shapes
from beacon_sim.core.distance_curves import difference_curve
from beacon_sim.core.raycast import cast_rays
from beacon_sim.core.sensor_kinds import is_scan
from beacon_sim.core.trilateration import Fix, TrilaterationError, trilaterate
from beacon_sim.evaluation.live_bound import LiveBound

#: Results kept per kind (a tick's worth, and the frames that show it).
KEEP = 64
#: Ticks of the bound kept: the tick shown is at most a few behind the newest one fed.
BOUND_TICKS = 512

_OUTLINES: dict[tuple, tuple] = {}
_WALLS: dict[tuple, tuple] = {}
_FIXES: dict[tuple, tuple] = {}
_CURVES: dict[tuple, tuple] = {}


def _keep(store: dict, key: tuple, value: tuple) -> None:
    if len(store) > KEEP:
        store.clear()
    store[key] = value


def sensor_outline(pose, spec, grid) -> np.ndarray:
    """``shapes.sensor_outline(pose, spec.fov, spec.max_range, grid)`` [m], kept by the pose,
    the field of view, the range and the grid."""
    key = (np.asarray(pose, dtype=float).tobytes(), float(spec.fov), float(spec.max_range), id(grid))
    hit = _OUTLINES.get(key)
    if hit is not None and hit[0] is grid:
        return hit[1]
    out = shapes.sensor_outline(pose, spec.fov, spec.max_range, grid)
    _keep(_OUTLINES, key, (grid, out))
    return out


def scan_walls(grid, pose, m, max_range: float) -> np.ndarray:
    """The range [m] to the first wall along each beam of the scan ``m`` taken at ``pose``
    (``cast_rays`` up to ``max_range``), kept by the reading, the pose and the grid."""
    key = (id(m), np.asarray(pose, dtype=float).tobytes(), float(max_range), id(grid))
    hit = _WALLS.get(key)
    if hit is not None and hit[0] is grid and hit[1] is m:
        return hit[2]
    z = np.asarray(m.z, dtype=float)
    wall = cast_rays(grid, np.asarray(pose[:2], dtype=float), pose[2] + z[:, 1], max_range)
    _keep(_WALLS, key, (grid, m, wall))
    return wall


def tdoa_fix(m, bxy: np.ndarray, height: float, s: float) -> Fix | None:
    """``trilaterate`` of the TDOA reading ``m`` against the beacons ``bxy`` (reference first)
    ``height`` above the receiver, arrivals of noise ``s`` [m]; None when it gives no fix.
    Kept by the reading and those numbers."""
    key = (id(m), np.asarray(bxy, dtype=float).tobytes(), float(height), float(s))
    hit = _FIXES.get(key)
    if hit is not None and hit[0] is m:
        return hit[1]
    try:
        fix: Fix | None = trilaterate(m.z[:, 0], bxy[0], bxy[1:], height, s)
    except TrilaterationError:
        fix = None
    _keep(_FIXES, key, (m, fix))
    return fix


def tdoa_curves(m, bxy: np.ndarray, height: float, pose, reach: float) -> list:
    """The curve (``difference_curve``, or None) of each range difference of the TDOA reading
    ``m`` against the beacons ``bxy`` (reference first), traced through the true ``pose``'s
    x-y out to ``reach`` [m]; kept by the reading, the pose and those numbers."""
    key = (id(m), np.asarray(bxy, dtype=float).tobytes(), float(height),
           np.asarray(pose, dtype=float).tobytes(), float(reach))
    hit = _CURVES.get(key)
    if hit is not None and hit[0] is m:
        return hit[1]
    curves = [difference_curve(bxy[0], b, float(d), height, pose[:2], reach)
              for b, d in zip(bxy[1:], m.z[:, 0], strict=True)]
    _keep(_CURVES, key, (m, curves))
    return curves


class DrawingAhead:
    """Called on the worker with each tick fed (``session.on_worker_step``): what the drawing
    of that tick will ask for, computed there."""

    def __init__(self, session):
        self.session = session

    def __call__(self, step) -> None:
        team = self.session.team
        world = team.world
        grid = getattr(world, "grid", None)
        for robot, s in zip(team.robots, step.steps, strict=True):
            sensors = robot.scenario.sensors
            pose = s.true_pose
            for spec in sensors:
                walled = getattr(spec, "occluded_by_walls", False)
                if grid is not None and walled and math.isfinite(spec.max_range):
                    sensor_outline(pose, spec, grid)
            for m in s.measurements:
                spec = next((x for x in sensors if x.name == m.sensor), None)
                if spec is None or not len(m):
                    continue
                if is_scan(m.kind) and grid is not None:
                    scan_walls(grid, pose, m, spec.max_range)
                elif m.kind == "tdoa":
                    bxy = world.beacon_positions(m.beacon_ids)
                    tdoa_curves(m, bxy, spec.beacon_height, pose, 1.5 * math.hypot(world.width, world.height))
                    tdoa_fix(m, bxy, spec.beacon_height, spec.noise.range_std)


class TickBound:
    """The live bound (``evaluation.live_bound.LiveBound``) of a one-robot session, fed with
    each tick where its filters are fed (on the worker; without one, when the tick is shown)
    and read as of the tick the window shows: ``valid``, ``P`` (3, 3), ``sigmas()``."""

    def __init__(self, session):
        self.session = session
        self.live = LiveBound(session.scenario)
        self._at: dict[int, tuple] = {}  # tick -> (P, sigmas) after it; (None, None): not valid
        self._last = 0
        session.on_step.append(self._shown)
        session.on_worker_step.append(lambda step: self.feed(step.steps[0]))

    def _shown(self, step) -> None:
        if getattr(self.session, "worker", None) is None:  # no worker: fed when shown
            self.feed(step)

    def feed(self, step) -> None:
        """One tick (``LiveBound.feed``), kept as of its tick."""
        if step.tick <= self._last:  # a fresh start
            self._at.clear()
        self._last = step.tick
        live = self.live
        live.feed(step)
        self._at[step.tick] = (live.P, live.sigmas()) if live.valid else (None, None)
        self._at.pop(step.tick - BOUND_TICKS, None)

    def _now(self) -> tuple:
        return self._at.get(self.session.tick_count, (None, None))

    @property
    def tick(self) -> int:
        """The last tick fed; -1: joined mid-run, no bound (``LiveBound.tick``)."""
        return self.live.tick

    @property
    def valid(self) -> bool:
        return self._now()[0] is not None

    @property
    def P(self) -> np.ndarray:
        return self._now()[0]

    def sigmas(self) -> tuple[float, float]:
        return self._now()[1]


__all__ = ["DrawingAhead", "TickBound", "scan_walls", "sensor_outline", "tdoa_curves", "tdoa_fix"]
