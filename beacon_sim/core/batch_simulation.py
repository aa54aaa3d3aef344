"""R runs of one scenario simulated together: the truth and the beacon sensors as (R, ...)
arrays, bit for bit the steps of R single :class:`~beacon_sim.core.simulation.Simulation`
runs (the Monte Carlo evaluation's simulation; tests/core/test_batch_simulation.py compares).

Each run keeps its own random streams, driver and checksums: a :class:`Simulation` per run
holds them, and every tick draws from each run's streams exactly what its own ``step``
would, in the same order. What is shared is the arithmetic: the motion model, the walls,
the visibility, the expected readings of every beacon, the outliers and the wrapping for
all runs in a few array operations instead of one Python call chain per run. The
single-run path is untouched.

Two ways to take a tick: :meth:`BatchSimulation.step` gives one :class:`Step` per run (the
objects a filter reads); :meth:`BatchSimulation.advance` gives the tick as arrays
(:class:`BatchTick`: poses, commands, and each beacon sensor's readings as a (R, n) mask
and (R, n, d) values over the map's beacons), which ``SlotPacker.pack_tick`` packs for the
batched filters without building a ``Measurement`` or ``Step`` per run. Both advance the
same state and draw the same numbers; they may be mixed.

Checksums: the truth checksum is taken from the stored poses when asked for (the same bytes
in the same order as a single run's); the readings checksum from the arrays, each tick,
unless the batch was made with ``readings_checksums=False`` (``eval`` never reports it).

Not here: user commands (a kidnap requested from the window) - a Monte Carlo run has none.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from beacon_sim.core import portable_math as pm
from beacon_sim.core.angles import wrap
from beacon_sim.core.drivers import CircleSpec, ConstantSpec, KeyboardSpec, RandomGoalSpec, WaypointsSpec
from beacon_sim.core.measurement_models import relative_bearing
from beacon_sim.core.motion import move_portable
from beacon_sim.core.scenario import Scenario
from beacon_sim.core.sensor_kinds import draw
from beacon_sim.core.sensors import SensorSpec, visible_mask
from beacon_sim.core.simulation import Simulation, _kidnap_text, bumped_heading, into_wall
from beacon_sim.core.types import Control, EventRecord, Measurement, Step

_BEACON_KINDS = ("bearing", "range_bearing")
#: Poses kept for the truth checksums before they are hashed (bounds the memory).
_TRUTH_PENDING = 1024
_NAN_BYTES = np.float64(float("nan")).tobytes()   # a beacon reading's HDOP in the checksum


@dataclass(frozen=True, eq=False)
class BeaconReadings:
    """One bearing or range-bearing sensor's readings on one tick, for every run.

    seen : (R, n) bool, beacon j of the map (``World.beacons`` order) read in run i.
    z : (R, n, d) [m, rad] the readings (range before bearing); only the seen entries are
        readings, the others are meaningless. Run i's ``Measurement`` is
        ``z[i, seen[i]]`` with ``beacon_ids[seen[i]]``.
    """

    sensor: str
    kind: str
    seen: np.ndarray
    z: np.ndarray
    beacon_ids: np.ndarray

    def measurement(self, i: int) -> Measurement | None:
        """Run ``i``'s reading as the single run's ``sense`` gives it (None: no beacon)."""
        idx = np.flatnonzero(self.seen[i])
        if idx.size == 0:
            return None
        return Measurement(self.sensor, self.kind, self.z[i, idx], self.beacon_ids[idx])


@dataclass(frozen=True, eq=False)
class OtherReadings:
    """A sensor of another kind (a pose or position fix) on one tick: each run's reading."""

    sensor: str
    kind: str
    per_run: list[Measurement | None]

    def measurement(self, i: int) -> Measurement | None:
        return self.per_run[i]


@dataclass(frozen=True, eq=False)
class BatchTick:
    """One tick of R runs as arrays (read-only by convention; ``pose`` is read-only).

    pose : (R, 3) true poses after the tick [m, m, rad].
    v, omega : (R,) the commands the filters see [m/s, rad/s] (v = 0 where the bumper
        stopped the robot).
    kidnapped : (R,) bool.
    readings : the sensors that reported on this tick (not blacked out), in the scenario's
        order.
    """

    tick: int
    time: float
    dt: float
    pose: np.ndarray
    v: np.ndarray
    omega: np.ndarray
    kidnapped: np.ndarray
    readings: tuple[BeaconReadings | OtherReadings, ...]
    events: tuple[tuple[EventRecord, ...], ...]

    def measurements(self, i: int) -> tuple[Measurement, ...]:
        """Run ``i``'s readings as ``Simulation.step`` gives them."""
        got = (r.measurement(i) for r in self.readings)
        return tuple(m for m in got if m is not None)

    def steps(self) -> list[Step]:
        """One :class:`Step` per run."""
        k, t, dt, pose = self.tick, self.time, self.dt, self.pose
        v, w = self.v.tolist(), self.omega.tolist()
        return [Step(k, t, dt, pose[i].copy(), Control(v[i], w[i]), self.measurements(i), self.events[i])
                for i in range(len(v))]


def steer(pose: np.ndarray, goal: np.ndarray, speed: float, gain: float, max_omega: float
          ) -> tuple[np.ndarray, np.ndarray]:
    """``drivers.steer_towards`` for R poses (R, 3) and goals (R, 2): (v, omega) (R,), bit for
    bit its floats. Every step is the same IEEE operation: the differences and products on
    arrays; atan2 and cos are the portable kernels' (core/portable_math.py, the same bits on
    arrays and floats); ``wrap`` on arrays is the float form's ``%`` (numpy's remainder is fmod
    plus the divisor when the signs differ, as Python's float ``%``); ``max``/``min`` are
    selections written as Python evaluates them (NaN and signed zeros included)."""
    dx = goal[:, 0] - pose[:, 0]
    dy = goal[:, 1] - pose[:, 1]
    err = wrap(relative_bearing(dx, dy, pose[:, 2], portable=True))
    om = gain * err
    om = np.where(-max_omega > om, -max_omega, om)      # max(gain err, -max_omega)
    om = np.where(max_omega < om, max_omega, om)        # min(., max_omega)
    c = pm.cos(err)
    return speed * np.where(c > 0.0, c, 0.0), om        # speed * max(0.0, cos(err))


class BatchSimulation:
    """``len(seeds)`` runs of ``scenario``, stepped together.

    ``step()`` returns one :class:`Step` per run, equal (bit for bit) to what
    ``Simulation(scenario, seed).step()`` returns for each seed at that tick; ``advance()``
    the same tick as arrays. ``readings_checksums``: False skips the readings checksums
    (then :meth:`readings_checksums` raises).

    The readings always carry their beacon IDs: a sensor with ``correspondence = "unknown"``
    is simulated as if its IDs were told (the same truth and readings, no clutter). Such runs
    are never batched (``BatchableFilter.batch_blocker``).
    """

    def __init__(self, scenario: Scenario, seeds: list[int], readings_checksums: bool = True):
        self.scenario = scenario
        self._sims = [Simulation(scenario, s) for s in seeds]
        self.dt = scenario.dt
        self.world = scenario.world
        self.tick = 0
        self.pose = np.stack([s.pose for s in self._sims])          # (R, 3)
        self.pose.flags.writeable = False
        first = self._sims[0]                                      # the schedules: same for all
        self.schedule = first.schedule
        self._kidnaps = first._kidnaps
        self._edges = first._interval_edges
        self._hash_readings = readings_checksums
        self._truth_pending: list[np.ndarray] = []   # poses not yet in the truth checksums
        self._synced = 0                             # the tick the Simulation objects are at
        spec = first.driver.spec
        self._points = np.array(spec.points, dtype=float).reshape(-1, 2) \
            if isinstance(spec, WaypointsSpec) else None
        self._goals: np.ndarray | None = None        # random goals (R, 2), once asked for
        self._has_goal = np.zeros(len(seeds), dtype=bool)

    def __len__(self) -> int:
        return len(self._sims)

    @property
    def time(self) -> float:
        return self.tick * self.dt

    @property
    def sims(self) -> list[Simulation]:
        """Each run's :class:`Simulation` (its streams, driver, pose, tick and checksums)."""
        self._sync()
        return self._sims

    def _sync(self) -> None:
        """Bring the Simulation objects' tick, pose and truth checksum up to date."""
        if self._truth_pending:
            poses = np.stack(self._truth_pending)                 # (P, R, 3)
            self._truth_pending.clear()
            for i, s in enumerate(self._sims):
                s._hash.update(poses[:, i].tobytes())   # = one update per tick, row by row
        if self._synced != self.tick:
            for i, s in enumerate(self._sims):
                s.tick = self.tick
                s.pose = self.pose[i].copy()
            self._synced = self.tick

    def truth_checksums(self) -> list[str]:
        return [s.truth_checksum for s in self.sims]

    def readings_checksums(self) -> list[str]:
        if not self._hash_readings:
            raise RuntimeError("this batch was made with readings_checksums=False")
        return [s.readings_checksum for s in self.sims]

    def step(self) -> list[Step]:
        """Advance every run one tick (each run's driver gives its command)."""
        return self.advance().steps()

    def advance(self) -> BatchTick:
        """Advance every run one tick; the tick as arrays."""
        sims, dt, world = self._sims, self.dt, self.world
        R = len(sims)
        old = self.pose
        t = self.time
        cv, cw = self._commands(t, old)
        v0 = cv.tolist()                               # the commands as given (bump events)
        self.tick += 1
        k = self.tick
        edges = tuple(self._edges.get(k, ()))
        extra: dict[int, list[EventRecord]] = {}     # bumps and kidnaps, by run

        # Truth: every run's command with its own motion noise, the model on arrays.
        noise = self.scenario.motion_noise
        sv, sw = noise.control_std(cv, cw)
        g = np.broadcast_to(noise.slip_gain(cv, cw), (R,)).tolist()  # slip scales with the command
        for burst in self.schedule.bursts_at(k):   # the portable hypot, as the single run does
            sv = pm.hypot(sv, np.multiply(g, burst.v_std))
            sw = pm.hypot(sw, np.multiply(g, burst.omega_std))
        E = np.empty((R, 5))
        for i, s in enumerate(sims):
            s._motion_rng.standard_normal(out=E[i])
        v = cv + sv * E[:, 0]
        w = cw + sw * E[:, 1]
        pose = move_portable(old, v, w, dt)
        pose += noise.pose_std_at(cv, cw) * E[:, 2:]
        pose[:, 2] = wrap(pose[:, 2])
        inside = world.contains(pose[:, :2])
        if world.grid is not None:                       # walls are solid
            r = self.scenario.robot_radius
            inside &= np.array([not into_wall(world, old[i], pose[i], r) for i in range(R)])
        if not np.all(inside):
            for i in np.flatnonzero(~inside).tolist():   # the bumper (see Simulation.step)
                if noise.slip_gain(0.0, cw[i]) != g[i]:   # the told command's turn and slip
                    pose[i, 2] = bumped_heading(noise, self.schedule.bursts_at(k), old[i, 2], cw[i],
                                                E[i, 1], E[i, 4], dt)
                pose[i] = world.clip(np.array([old[i, 0], old[i, 1], pose[i, 2]]))
                if v0[i] != 0.0:
                    extra.setdefault(i, []).append(EventRecord("bump", k, k * dt, "stopped at the wall"))
                cv[i] = 0.0   # the command the filters see: v = 0 (Control(0.0, omega))

        kidnapped = np.zeros(R, dtype=bool)
        for kid in self._kidnaps.get(k, ()):
            kidnapped[:] = True
            for i, s in enumerate(sims):
                target = kid.target(pose[i].copy(), world, s._events_rng)
                extra.setdefault(i, []).append(EventRecord("kidnap", k, k * dt, _kidnap_text(kid),
                                                           pose[i].copy(), target))
                pose[i] = target
        pose.flags.writeable = False
        self.pose = pose
        self._truth_pending.append(pose)
        if len(self._truth_pending) >= _TRUTH_PENDING:
            self._sync()

        readings: list[BeaconReadings | OtherReadings] = []
        for spec in self.scenario.sensors:
            if not self.schedule.due(spec.name, k):
                continue
            blacked = self.schedule.blacked_out(spec.name, k)
            got: BeaconReadings | OtherReadings | None
            if spec.kind in _BEACON_KINDS:
                got = self._sense_beacons(spec, pose)
            else:
                per_run = [draw(spec, pose[i], world, s._sensor_rngs[spec.name]) for i, s in enumerate(sims)]
                got = OtherReadings(spec.name, spec.kind, per_run) \
                    if any(m is not None for m in per_run) else None
            if blacked or got is None:
                continue
            readings.append(got)
            if self._hash_readings:
                self._hash_tick(k, got)
        if extra:
            events = tuple(edges + tuple(extra.get(i, ())) for i in range(R))
        else:
            events = (edges,) * R
        return BatchTick(k, k * dt, dt, pose, cv, cw, kidnapped, tuple(readings), events)

    def _commands(self, t: float, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each run's driver's command (v, omega) (R,) for the tick that starts at ``t``
        [s] from ``pose`` (R, 3): what ``Driver.control`` gives, bit for bit. Constant
        commands are the spec's; waypoints and random goals steer with :func:`steer` (the
        goal test on arrays, see :meth:`_reached`); any other driver is asked run by run."""
        sims = self._sims
        R = len(sims)
        spec = sims[0].driver.spec
        if isinstance(spec, ConstantSpec):
            return np.full(R, spec.v, dtype=float), np.full(R, spec.omega, dtype=float)
        if isinstance(spec, CircleSpec):
            return np.full(R, spec.speed, dtype=float), np.full(R, spec.speed / spec.radius, dtype=float)
        if isinstance(spec, KeyboardSpec):
            return np.zeros(R), np.zeros(R)
        if isinstance(spec, WaypointsSpec):
            return self._waypoints(spec, pose)
        if isinstance(spec, RandomGoalSpec):
            return self._random_goals(spec, pose)
        controls = [s.driver.control(t, pose[i]) for i, s in enumerate(sims)]
        return (np.array([c.v for c in controls], dtype=float),
                np.array([c.omega for c in controls], dtype=float))

    @staticmethod
    def _reached(goal: np.ndarray, pose: np.ndarray, tol: float) -> np.ndarray:
        """``drivers.arrived`` (the drivers' arrival test) for every run (R,): the portable
        hypot gives the same bits on arrays as on floats."""
        return pm.hypot(goal[:, 0] - pose[:, 0], goal[:, 1] - pose[:, 1]) < tol

    def _waypoints(self, spec: WaypointsSpec, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``Driver.control`` of a waypoints driver for every run; each run's waypoint index
        stays in its ``Driver``."""
        drivers = [s.driver for s in self._sims]
        R = len(drivers)
        pts = self._points
        assert pts is not None
        n = len(pts)
        v = np.zeros(R)
        w = np.zeros(R)
        if n == 0:
            return v, w
        index = np.array([d._index for d in drivers])
        live = index < n
        reached = self._reached(pts[np.minimum(index, n - 1)], pose, spec.tolerance)
        for i in np.flatnonzero(reached & live).tolist():
            d = drivers[i]
            d._index += 1
            if spec.loop:
                d._index %= n
            index[i] = d._index
        go = index < n
        if go.all():
            return steer(pose, pts[index], spec.speed, spec.gain, spec.max_omega)
        if go.any():
            v[go], w[go] = steer(pose[go], pts[index[go]], spec.speed, spec.gain, spec.max_omega)
        return v, w

    def _random_goals(self, spec: RandomGoalSpec, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``Driver.control`` of a random-goal driver for every run: a run without a goal,
        or at its goal, draws a new one from its driver's stream (as the driver does, into
        the driver's ``_goal``)."""
        drivers = [s.driver for s in self._sims]
        if self._goals is None:
            self._goals = np.array([(0.0, 0.0) if d._goal is None else d._goal for d in drivers],
                                   dtype=float).reshape(-1, 2)
            self._has_goal = np.array([d._goal is not None for d in drivers])
        goals = self._goals
        new = ~self._has_goal | self._reached(goals, pose, spec.tolerance)
        if new.any():
            xmin, ymin, xmax, ymax = self.world.bounds
            for i in np.flatnonzero(new).tolist():
                d = drivers[i]
                d._goal = np.array([d.rng.uniform(xmin + spec.margin, xmax - spec.margin),
                                    d.rng.uniform(ymin + spec.margin, ymax - spec.margin)])
                goals[i] = d._goal
            self._has_goal[:] = True
        return steer(pose, goals, spec.speed, spec.gain, spec.max_omega)

    def _hash_tick(self, k: int, got: BeaconReadings | OtherReadings) -> None:
        """Each run's reading of one sensor into its readings checksum, as Simulation.step
        hashes it (sensor, kind, z's shape, z, beacon IDs, HDOP)."""
        sims = self._sims
        if isinstance(got, OtherReadings):
            for i, m in enumerate(got.per_run):
                if m is None:
                    continue
                h = sims[i]._readings_hash
                h.update(f"{k} {m.sensor} {m.kind} {m.z.shape}".encode())
                h.update(np.ascontiguousarray(m.z, dtype="<f8").tobytes())
                h.update(np.ascontiguousarray(m.beacon_ids, dtype="<i8").tobytes())
                h.update(np.float64(m.hdop).tobytes())
            return
        seen, z = got.seen, got.z
        d = z.shape[-1]
        counts = np.count_nonzero(seen, axis=1).tolist()
        ids = np.ascontiguousarray(got.beacon_ids, dtype="<i8")
        head = f"{k} {got.sensor} {got.kind} "
        for i, c in enumerate(counts):
            if not c:
                continue
            sel = seen[i]
            sims[i]._readings_hash.update(b"".join((
                f"{head}{(c, d)}".encode(),
                np.ascontiguousarray(z[i, sel], dtype="<f8").tobytes(),
                ids[sel].tobytes(),
                _NAN_BYTES)))

    def _sense_beacons(self, spec: SensorSpec, pose: np.ndarray) -> BeaconReadings | None:
        """``sensors.sense`` of a bearing or range-bearing sensor for every run: each run's
        draws from its own stream (the same, in the same order, as ``sense``), the geometry,
        the noise, the outliers and the wrapping of all runs and beacons at once (element by
        element the operations ``sense`` does on its run's seen beacons). None: no run saw
        a beacon."""
        world = self.world
        sims = self._sims
        R = len(sims)
        n = len(world.beacons)
        n1 = max(n, 1)
        d = 1 if spec.kind == "bearing" else 2
        u_detect = np.empty((R, n))
        noise = np.empty((R, n, d))
        u_outlier = np.empty((R, n1))
        u_value = np.empty((R, n1, d))
        for i, s in enumerate(sims):
            rng = s._sensor_rngs[spec.name]
            rng.random(out=u_detect[i])
            rng.standard_normal(out=noise[i])
            rng.random(out=u_outlier[i])
            rng.random(out=u_value[i])
        diff = world.beacon_xy[None, :, :] - pose[:, None, :2]   # (R, n, 2)
        dx, dy = diff[..., 0], diff[..., 1]
        seen = visible_mask(spec, pose, world)  # range, field of view, walls (sensors.py)
        seen &= u_detect < spec.detection_prob
        if not seen.any():
            return None
        bearing = wrap(relative_bearing(dx, dy, pose[:, 2, None], portable=True))  # (R, n), as sense
        if spec.kind == "bearing":
            z = bearing[..., None] + noise * spec.noise.bearing_std
        else:
            h = np.empty((*bearing.shape, 2))
            h[..., 0] = pm.hypot(dx, dy)
            h[..., 1] = bearing
            z = h + noise * spec.reading_std()
        if spec.outlier_rate > 0.0:
            bad = u_outlier[:, :n] < spec.outlier_rate
            if spec.kind == "bearing":
                z[bad, 0] = -math.pi + 2.0 * math.pi * u_value[:, :n][bad, 0]
            else:
                max_r = (spec.max_range if math.isfinite(spec.max_range)
                         else max(world.width, world.height))
                z[bad, 0] = max_r * u_value[:, :n][bad, 0]
                z[bad, 1] = -math.pi + 2.0 * math.pi * u_value[:, :n][bad, 1]
        if spec.kind == "bearing":
            z[..., 0] = wrap(z[..., 0])
        else:
            z[..., 0] = np.abs(z[..., 0])
            z[..., 1] = wrap(z[..., 1])
        return BeaconReadings(spec.name, spec.kind, seen, z, world.beacon_ids)

    def run(self, duration: float) -> list[list[Step]]:
        """Step for ``duration`` seconds; one list of steps per run."""
        per_run: list[list[Step]] = [[] for _ in self._sims]
        for _ in range(round(duration / self.dt)):
            for lst, st in zip(per_run, self.step(), strict=True):
                lst.append(st)
        return per_run


__all__ = ["BatchSimulation", "BatchTick", "BeaconReadings", "OtherReadings", "steer"]
