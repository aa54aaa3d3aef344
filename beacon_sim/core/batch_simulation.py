"""R runs of one scenario simulated together: the truth and the beacon sensors as (R, ...)
arrays, bit for bit the steps of R single :class:`~beacon_sim.core.simulation.Simulation`
runs (the Monte Carlo evaluation's simulation; tests/test_batch_simulation.py compares).

Each run keeps its own random streams, driver and checksums: a :class:`Simulation` per run
holds them, and :meth:`BatchSimulation.step` draws from each run's streams exactly what its
own ``step`` would, in the same order. What is shared is the arithmetic: the motion model,
the walls, the visibility and the expected readings of every beacon for all runs in a few
array operations instead of one Python call chain per run. The single-run path is untouched.

Not here: user commands (a kidnap requested from the window) - a Monte Carlo run has none.
"""

from __future__ import annotations

import math

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.motion import move
from beacon_sim.core.scenario import Scenario
from beacon_sim.core.sensors import SensorSpec, sense
from beacon_sim.core.simulation import Simulation, _kidnap_text
from beacon_sim.core.types import Control, EventRecord, Measurement, Step

_BEACON_KINDS = ("bearing", "range_bearing")


class BatchSimulation:
    """``len(seeds)`` runs of ``scenario``, stepped together.

    ``step()`` returns one :class:`Step` per run, equal (bit for bit) to what
    ``Simulation(scenario, seed).step()`` returns for each seed at that tick.
    """

    def __init__(self, scenario: Scenario, seeds: list[int]):
        self.scenario = scenario
        self.sims = [Simulation(scenario, s) for s in seeds]
        self.dt = scenario.dt
        self.world = scenario.world
        self.tick = 0
        self.pose = np.stack([s.pose for s in self.sims])          # (R, 3)
        first = self.sims[0]                                       # the schedules: same for all
        self._every = first._every
        self._kidnaps = first._kidnaps
        self._blackouts = first._blackout_ticks
        self._bursts = first._burst_ticks
        self._edges = first._interval_edges

    def __len__(self) -> int:
        return len(self.sims)

    @property
    def time(self) -> float:
        return self.tick * self.dt

    def truth_checksums(self) -> list[str]:
        return [s.truth_checksum for s in self.sims]

    def readings_checksums(self) -> list[str]:
        return [s.readings_checksum for s in self.sims]

    def step(self) -> list[Step]:
        """Advance every run one tick (each run's driver gives its command)."""
        sims, dt, world = self.sims, self.dt, self.world
        R = len(sims)
        old = self.pose
        t = self.time
        controls = [s.driver.control(t, old[i]) for i, s in enumerate(sims)]
        self.tick += 1
        k = self.tick
        for s in sims:
            s.tick = k
        edges = self._edges.get(k, ())
        events: list[list[EventRecord]] = [list(edges) for _ in range(R)]

        # Truth: every run's command with its own motion noise, the model on arrays.
        noise = self.scenario.motion_noise
        cv = np.array([c.v for c in controls])
        cw = np.array([c.omega for c in controls])
        sv, sw = noise.control_std(cv, cw)
        for burst in self._bursts.get(k, ()):   # math.hypot per run, as the single run does
            sv = np.array([math.hypot(x, burst.v_std) for x in sv.tolist()])
            sw = np.array([math.hypot(x, burst.omega_std) for x in sw.tolist()])
        E = np.stack([s._motion_rng.standard_normal(5) for s in sims])
        v = cv + sv * E[:, 0]
        w = cw + sw * E[:, 1]
        pose = move(old, v, w, dt)
        pose += np.asarray(noise.pose_std) * E[:, 2:]
        pose[:, 2] = (pose[:, 2] + math.pi) % (2 * math.pi) - math.pi
        inside = world.contains(pose[:, :2])
        for i in np.flatnonzero(~inside).tolist():   # the bumper (see Simulation.step)
            pose[i] = world.clip(np.array([old[i, 0], old[i, 1], pose[i, 2]]))
            if controls[i].v != 0.0:
                events[i].append(EventRecord("bump", k, k * dt, "stopped at the wall"))
            controls[i] = Control(0.0, controls[i].omega)

        for kid in self._kidnaps.get(k, ()):
            for i, s in enumerate(sims):
                target = kid.target(pose[i].copy(), world, s._events_rng)
                events[i].append(EventRecord("kidnap", k, k * dt, _kidnap_text(kid), pose[i].copy(),
                                             target))
                pose[i] = target
        self.pose = pose
        for i, s in enumerate(sims):
            s._hash.update(pose[i].tobytes())

        measurements: list[list[Measurement]] = [[] for _ in range(R)]
        blackouts = self._blackouts.get(k, ())
        for spec in self.scenario.sensors:
            if k % self._every[spec.name]:
                continue
            blacked = any(b.covers(spec.name) for b in blackouts)
            if spec.kind in _BEACON_KINDS:
                got = self._sense_beacons(spec, pose)
            else:
                got = [sense(spec, pose[i], world, s._sensor_rngs[spec.name]) for i, s in enumerate(sims)]
            if blacked:
                continue
            for i, m in enumerate(got):
                if m is None:
                    continue
                measurements[i].append(m)
                h = sims[i]._readings_hash
                h.update(f"{k} {m.sensor} {m.kind} {m.z.shape}".encode())
                h.update(np.ascontiguousarray(m.z, dtype="<f8").tobytes())
                h.update(np.ascontiguousarray(m.beacon_ids, dtype="<i8").tobytes())
                h.update(np.float64(m.hdop).tobytes())
        for i, s in enumerate(sims):
            s.pose = pose[i].copy()
        return [Step(k, k * dt, dt, pose[i].copy(), controls[i], tuple(measurements[i]), tuple(events[i]))
                for i in range(R)]

    def _sense_beacons(self, spec: SensorSpec, pose: np.ndarray) -> list[Measurement | None]:
        """``sensors.sense`` of a bearing or range-bearing sensor for every run: each run's
        draws from its own stream, the geometry of all runs and beacons at once."""
        world = self.world
        n = len(world.beacons)
        d = 1 if spec.kind == "bearing" else 2
        draws = []
        for s in self.sims:   # the same draws, in the same order, as sense()
            rng = s._sensor_rngs[spec.name]
            draws.append((rng.random(n), rng.standard_normal((n, d)), rng.random(max(n, 1)),
                          rng.random((max(n, 1), d))))
        u_detect = np.stack([x[0] for x in draws])            # (R, n)
        noise = np.stack([x[1] for x in draws])               # (R, n, d)
        diff = world.beacon_xy[None, :, :] - pose[:, None, :2]   # (R, n, 2)
        dx, dy = diff[..., 0], diff[..., 1]
        seen = np.hypot(dx, dy) <= spec.max_range
        if spec.fov < 2.0 * math.pi:
            rel = wrap(np.arctan2(dy, dx) - pose[:, 2, None])
            seen &= np.abs(rel) <= 0.5 * spec.fov
        seen &= u_detect < spec.detection_prob
        if not seen.any():
            return [None] * len(self.sims)
        bearing = wrap(np.arctan2(dy, dx) - pose[:, 2, None])  # (R, n)
        if spec.kind == "bearing":
            z_all = bearing[..., None] + noise * spec.noise.bearing_std
        else:
            h = np.empty((*bearing.shape, 2))
            h[..., 0] = np.hypot(dx, dy)
            h[..., 1] = bearing
            z_all = h + noise * spec.reading_std()
        out: list[Measurement | None] = []
        for i in range(len(self.sims)):
            idx = np.flatnonzero(seen[i])
            if idx.size == 0:
                out.append(None)
                continue
            z = z_all[i, idx]
            if spec.outlier_rate > 0.0:
                _, _, u_outlier, u_value = draws[i]
                bad = u_outlier[idx] < spec.outlier_rate
                if spec.kind == "bearing":
                    z[bad, 0] = -math.pi + 2.0 * math.pi * u_value[idx][bad, 0]
                else:
                    max_r = (spec.max_range if math.isfinite(spec.max_range)
                             else max(world.width, world.height))
                    z[bad, 0] = max_r * u_value[idx][bad, 0]
                    z[bad, 1] = -math.pi + 2.0 * math.pi * u_value[idx][bad, 1]
            if spec.kind == "bearing":
                z[:, 0] = wrap(z[:, 0])
            else:
                z[:, 0] = np.abs(z[:, 0])
                z[:, 1] = wrap(z[:, 1])
            out.append(Measurement(spec.name, spec.kind, z, world.beacon_ids[idx]))
        return out

    def run(self, duration: float) -> list[list[Step]]:
        """Step for ``duration`` seconds; one list of steps per run."""
        per_run: list[list[Step]] = [[] for _ in self.sims]
        for _ in range(round(duration / self.dt)):
            for lst, st in zip(per_run, self.step(), strict=True):
                lst.append(st)
        return per_run


__all__ = ["BatchSimulation"]
