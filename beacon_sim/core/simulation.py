"""The simulation: fixed ticks of ``dt`` seconds, truth, sensors and events.

``Simulation.step(control) -> Step``. The simulation knows nothing about filters. Same
scenario + seed + controls gives identical arrays, whatever else draws random numbers:
motion noise, each sensor, events and the driver each have their own stream.
"""

from __future__ import annotations

import hashlib
from dataclasses import replace

import numpy as np

from beacon_sim.core import portable_math as pm
from beacon_sim.core.angles import wrap
from beacon_sim.core.clutter import unlabel
from beacon_sim.core.drivers import Driver
from beacon_sim.core.events import Blackout, Kidnap, active_ticks, first_tick_at
from beacon_sim.core.motion import SLIP_MODELS, move_portable, with_slip
from beacon_sim.core.scenario import Scenario
from beacon_sim.core.schedule import tick_schedule
from beacon_sim.core.sensor_kinds import draw
from beacon_sim.core.streams import stream
from beacon_sim.core.types import Control, EventRecord, Measurement, Step


class Simulation:
    """Runs a :class:`Scenario` with a seed.

    Parameters
    ----------
    scenario : Scenario
    seed : int, optional
        Defaults to the scenario's seed.
    readings_seed : int, optional
        The seed of the sensors' and clutter's streams only (default ``seed``): the same
        truth, controls and events with the readings drawn again (``grade``'s probe of
        whether a filter uses its readings, drawn like any run's).
    """

    def __init__(self, scenario: Scenario, seed: int | None = None, readings_seed: int | None = None):
        self.scenario = scenario
        self.seed = scenario.seed if seed is None else int(seed)
        rs = self.seed if readings_seed is None else int(readings_seed)
        self.dt = scenario.dt
        self.world = scenario.world
        self.tick = 0
        self.pose = np.array(scenario.initial_pose, dtype=float)
        self._motion_rng = stream(self.seed, "motion")
        self._events_rng = stream(self.seed, "events")
        self._sensor_rngs = {s.name: stream(rs, "sensor", s.name) for s in scenario.sensors}
        # Unknown correspondence: clutter and the shuffle on streams of their own.
        self._clutter_rngs = {s.name: stream(rs, "clutter", s.name) for s in scenario.sensors
                              if s.correspondence == "unknown"}
        self.driver = Driver(scenario.driver, scenario.world, stream(self.seed, "driver"))
        self.schedule = tick_schedule(scenario)  # sensor periods, blackouts, bursts
        self._kidnaps: dict[int, list[Kidnap]] = {}
        self._interval_edges: dict[int, list[EventRecord]] = {}
        for ev in scenario.events:
            if isinstance(ev, Kidnap):
                self._kidnaps.setdefault(first_tick_at(ev.time, self.dt), []).append(ev)
                continue
            ticks = active_ticks(ev, self.dt)
            what = ", ".join(ev.sensors) if isinstance(ev, Blackout) and ev.sensors else ""
            self._interval_edges.setdefault(ticks.start, []).append(
                EventRecord(f"{ev.kind}_start", ticks.start, ticks.start * self.dt, what))
            self._interval_edges.setdefault(ticks.stop, []).append(
                EventRecord(f"{ev.kind}_end", ticks.stop, ticks.stop * self.dt, what))
        self._pending_kidnap: list[np.ndarray | None] = []
        self._hash = hashlib.sha256()
        self._hash.update(self.pose.tobytes())
        self._readings_hash = hashlib.sha256()

    @property
    def time(self) -> float:
        """Simulated time [s] of the current state."""
        return self.tick * self.dt

    @property
    def truth_checksum(self) -> str:
        """SHA-256 (first 16 hex digits) of every true pose so far, bit for bit."""
        return self._hash.hexdigest()[:16]

    @property
    def readings_checksum(self) -> str:
        """SHA-256 (first 16 hex digits) of every reading so far (sensor, kind, z, beacon IDs,
        HDOP, bit for bit): what a recording's replay checks besides the truth."""
        return self._readings_hash.hexdigest()[:16]

    def _into_wall(self, pose: np.ndarray) -> bool:
        return into_wall(self.world, self.pose, pose, self.scenario.robot_radius)

    def request_kidnap(self, pose=None) -> None:
        """Teleport the robot on the next step: to ``pose`` [x, y, theta], or a random pose
        (from the events stream) when None. Used by the window (K key, mouse click)."""
        self._pending_kidnap.append(None if pose is None else np.array(pose, dtype=float))

    def step(self, control: Control | None = None) -> Step:
        """Advance one tick. ``control`` None asks the scenario's driver for the command."""
        if control is None:
            control = self.driver.control(self.time, self.pose)
        self.tick += 1
        k = self.tick
        events: list[EventRecord] = list(self._interval_edges.get(k, ()))

        # Truth: the command executed with noise (plus any noise burst in force).
        noise = self.scenario.motion_noise
        # Slip scales with the command (MotionNoise.slip_gain): a stopped robot stays put,
        # in a noise burst too. The five draws are made whatever the command (stable streams).
        sv, sw = noise.control_std(control.v, control.omega)
        g = noise.slip_gain(control.v, control.omega)
        for burst in self.schedule.bursts_at(k):
            sv = pm.hypot1(sv, g * burst.v_std)
            sw = pm.hypot1(sw, g * burst.omega_std)
        e = self._motion_rng.standard_normal(5)
        v = control.v + sv * e[0]
        w = control.omega + sw * e[1]
        pose = move_portable(self.pose, v, w, self.dt)   # portable maths: same bits anywhere
        pose += noise.pose_std_at(control.v, control.omega) * e[2:]
        pose[2] = wrap(pose[2])
        if not self.world.contains(pose[:2]) or self._into_wall(pose):
            # The bumper: a move that would leave the room (or enter a wall) is not made. The
            # robot stays where it was (it may still turn), and the command the filters see
            # is what it did: v = 0. Runs that never reach a wall are not affected (same draws, same truth).
            # Its turn is the told command's, with that command's slip (bumped_heading).
            if noise.slip_gain(0.0, control.omega) != g:
                pose[2] = bumped_heading(noise, self.schedule.bursts_at(k), self.pose[2],
                                         control.omega, e[1], e[4], self.dt)
            pose = self.world.clip(np.array([self.pose[0], self.pose[1], pose[2]]))
            if control.v != 0.0:
                events.append(EventRecord("bump", k, k * self.dt, "stopped at the wall"))
            control = Control(0.0, control.omega)

        # Kidnaps: scheduled ones, then those the user asked for.
        for kid in self._kidnaps.get(k, ()):
            target = kid.target(pose, self.world, self._events_rng)
            events.append(EventRecord("kidnap", k, k * self.dt, _kidnap_text(kid), pose, target))
            pose = target
        for asked in self._pending_kidnap:
            if asked is None:
                target = Kidnap(0.0, random=True).target(pose, self.world, self._events_rng)
                text = "random (user)"
            else:
                target = self.world.clip(asked)
                text = "to a pose (user)"
            events.append(EventRecord("kidnap", k, k * self.dt, text, pose, target))
            pose = target
        self._pending_kidnap.clear()
        self.pose = pose
        self._hash.update(pose.tobytes())

        measurements: list[Measurement] = []
        true_ids: dict[str, np.ndarray] = {}
        for spec in self.scenario.sensors:
            if not self.schedule.due(spec.name, k):
                continue
            rng = self._sensor_rngs[spec.name]
            m = draw(spec, pose, self.world, rng)  # draw even when blacked out: stable streams
            ids = None
            if spec.name in self._clutter_rngs:  # IDs hidden, clutter added, truth kept aside
                m, ids = unlabel(m, spec, self._clutter_rngs[spec.name])
            if m is not None and not self.schedule.blacked_out(spec.name, k):
                measurements.append(m)
                if ids is not None:
                    true_ids[spec.name] = ids
                h = self._readings_hash
                h.update(f"{k} {m.sensor} {m.kind} {m.z.shape}".encode())
                h.update(np.ascontiguousarray(m.z, dtype="<f8").tobytes())
                h.update(np.ascontiguousarray(m.beacon_ids, dtype="<i8").tobytes())
                h.update(np.float64(m.hdop).tobytes())
        return Step(k, k * self.dt, self.dt, pose.copy(), control, tuple(measurements),
                    tuple(events), true_ids)

    def run(self, duration: float, controls=None) -> list[Step]:
        """Step for ``duration`` seconds; ``controls`` is an optional sequence of Control."""
        n = round(duration / self.dt)
        steps = []
        for i in range(n):
            steps.append(self.step(None if controls is None else controls[i]))
        return steps


def into_wall(world, old: np.ndarray, new: np.ndarray, radius: float) -> bool:
    """Whether the move from ``old`` to ``new`` takes the robot's disc of ``radius`` [m] into
    a wall (a world with walls only; a robot put inside one, by a kidnap, may drive out)."""
    if world.grid is None:
        return False
    return not world.is_free(new, radius) and world.is_free(old, radius)


def bumped_heading(noise, bursts, theta0: float, omega: float, e_omega: float, e_theta: float,
                   dt: float) -> float:
    """The heading [rad] after a tick the bumper stopped: the command the filters are told,
    v = 0 and ``omega`` [rad/s], executed with that command's noise (the draws ``e_omega``,
    ``e_theta`` of the tick). Slip scales with the command, so a robot pushed straight into
    a wall does not turn; with ``slip_gain`` equal for the given and the told
    command (the legacy model, or a turn of 0.1 rad/s and more) the caller keeps its own."""
    sw = float(noise.control_std(0.0, omega)[1])
    g = noise.slip_gain(0.0, omega)
    for burst in bursts:
        sw = pm.hypot1(sw, g * burst.omega_std)
    th = wrap(theta0 + (omega + sw * e_omega) * dt) + float(noise.pose_std_at(0.0, omega)[2]) * e_theta
    return wrap(th)


def _kidnap_text(kid: Kidnap) -> str:
    if kid.pose is not None:
        return "to " + ", ".join(f"{v:.2f}" for v in kid.pose)
    if kid.offset is not None:
        return "by " + ", ".join(f"{v:+.2f}" for v in kid.offset)
    return "random"


#: The slip model a recording's header names ("slip_model") when it was made under the
#: current one; a header without the key was made before 0.3.0: "legacy".
CURRENT_SLIP_MODEL = "scaled"
RECORDED_BEFORE_SLIP_MODEL = "legacy"


def scenario_with_slip(scenario: Scenario, model: str) -> Scenario:
    """``scenario`` with the truth's and the filters' motion noise under the slip model
    ``model`` (:data:`~beacon_sim.core.motion.SLIP_MODELS`; ValueError for another)."""
    if model not in SLIP_MODELS:
        raise ValueError(f"slip_model {model!r}: expected one of {', '.join(SLIP_MODELS)}")
    return replace(scenario, motion_noise=with_slip(scenario.motion_noise, model),
                   model_motion_noise=with_slip(scenario.model_motion_noise, model))
