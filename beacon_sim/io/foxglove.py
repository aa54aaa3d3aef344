"""A run as Foxglove topics, in Foxglove's official schemas (the ``foxglove-sdk`` package).

One :class:`Publisher` writes the same messages to an MCAP file (:mod:`beacon_sim.io.mcap`)
and to a live WebSocket server (:mod:`beacon_sim.io.foxglove_live`), so what Foxglove shows
of a file and of a live session is the same:

===============================  ==========================  ======================================
topic                            schema                      one message
===============================  ==========================  ======================================
``/world``                       foxglove.SceneUpdate        at the start: beacons (with their ID)
                                                             and the world's bounds
``/truth/pose``                  foxglove.PoseInFrame        per tick, tick 0 included
``/tf``                          foxglove.FrameTransform     per tick: ``world`` -> ``robot`` (truth)
``/truth/scene``                 foxglove.SceneUpdate        per tick: the true pose as an arrow
``/filters/NAME/pose``           foxglove.PoseInFrame        per tick with an estimate
``/filters/NAME/scene``          foxglove.SceneUpdate        same ticks: the estimate as an arrow
                                                             in the filter's colour, its 95 % x-y
                                                             ellipse, the covariance in metadata
``/filters/NAME/stats``          beacon_sim.FilterStats      same ticks: error, sigma, NEES, the
                                                             covariance (JSON; for the Plot panel)
``/trails``                      foxglove.SceneUpdate        per tick: the paths so far, truth and
                                                             each filter in its colour
``/readings``                    foxglove.SceneUpdate        per tick with readings: rays from the
                                                             true pose, living one sensor period
                                                             (a range finder's scans excluded)
``/map``                         foxglove.Grid               at the start, in a map world: the
                                                             occupancy grid (one INT8 field
                                                             ``occupancy``: 0 free, 100 occupied,
                                                             -1 unknown), its origin as the pose
``/scan/SENSOR``                 foxglove.LaserScan          per scan of range finder SENSOR: the
                                                             ranges [m], first / last beam angle
                                                             [rad], the true pose as the origin
``/events``                      foxglove.Log                per event and per filter switched off
``/filters/NAME/particles``      foxglove.PosesInFrame       per tick, a particle filter: at most
                                                             :data:`MAX_PARTICLES_SHOWN` particles
                                                             drawn systematically by weight (the
                                                             counts on ``/filters/NAME/stats``)
``/filters/NAME/grid``           foxglove.Grid               per tick, a grid filter: the x-y
                                                             probability (one FLOAT32 field
                                                             ``probability``, heading summed out)
``/filters/NAME/map``            foxglove.SceneUpdate        per tick, a SLAM filter: each landmark
                                                             (a sphere, its label) and its 95 %
                                                             ellipse; the numbers in metadata
``/pcrb``                        foxglove.SceneUpdate        per tick when the bound is given: the
                                                             PCRB's 95 % x-y ellipse on the truth
``/pcrb/stats``                  beacon_sim.BoundStats       same ticks: its sigmas and covariance
``/readings/values``             beacon_sim.Readings         per tick with landmark readings: each
                                                             reading's numbers (JSON, plottable)
===============================  ==========================  ======================================

Frame ``world`` is the simulation's world frame (x right, y up, metres; z = 0 the floor); a
heading theta [rad] is the rotation about +z. Time stamps are simulated time: tick ``k`` is
``k * dt`` seconds after the epoch (Foxglove shows 1970-01-01), in nanoseconds. The numbers of
``/filters/NAME/stats`` are those of the ``estimates`` table (:mod:`beacon_sim.io.tables`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from beacon_sim.core import sensor_kinds
from beacon_sim.core.angles import wrap
from beacon_sim.core.optional import install_hint
from beacon_sim.core.scenario import Scenario
from beacon_sim.core.sensor_kinds import is_scan, names_beacons, scan_sensors
from beacon_sim.filters.base import GridBelief, LandmarkMap, ParticleBelief
from beacon_sim.io.foxglove_layout import layout
from beacon_sim.io.foxglove_schemas import (
    BOUND_COLOUR,
    BOUND_FIELDS,
    BOUND_SCHEMA,
    ELLIPSE_SCALE,
    FILTER_COLOURS,
    FRAME,
    JSON_SCHEMAS,
    MAX_PARTICLES_SHOWN,
    READING_COLOUR,
    READING_FIELDS,
    READINGS_SCHEMA,
    ROBOT_FRAME,
    STATS_FIELDS,
    STATS_SCHEMA,
    TRAIL_PIECE,
    TRUTH_COLOUR,
    colour_of,
    filter_stats,
)
from beacon_sim.io.tables import COV_COLUMNS, UPPER

INSTALL_HINT = install_hint("foxglove")


def foxglove_modules():
    """``(foxglove, foxglove.channels, foxglove.messages)``, or ImportError with the hint."""
    try:
        import foxglove
        from foxglove import channels, messages
    except ImportError as exc:
        raise ImportError(INSTALL_HINT) from exc
    return foxglove, channels, messages


def shown_particles(poses: np.ndarray, weights: np.ndarray, most: int = MAX_PARTICLES_SHOWN) -> np.ndarray:
    """At most ``most`` of the particles ``poses`` (N, 3): all when N <= ``most``, else a
    systematic draw by ``weights`` (the offsets (k + 1/2) / most: deterministic, no random
    numbers used), so the cloud shown has the belief's shape."""
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    if len(poses) <= most:
        return poses.copy()
    w = np.asarray(weights, dtype=float).reshape(-1)
    c = np.cumsum(w)
    idx = np.searchsorted(c, (np.arange(most) + 0.5) / most * c[-1])
    return poses[np.minimum(idx, len(poses) - 1)]


@dataclass(frozen=True)
class BeliefFrame:
    """What one tick shows beyond the estimates, as the window draws it.

    particles : name -> (shown poses (K, 3) [m, m, rad], the filter's particle count N)
    grids : name -> the x-y probability of a grid filter
    landmarks : name -> a SLAM filter's map
    bound : the PCRB (3, 3) [m^2, m^2, rad^2] at this tick, or None
    """

    particles: Mapping[str, tuple[np.ndarray, int]] = field(default_factory=dict)
    grids: Mapping[str, GridBelief] = field(default_factory=dict)
    landmarks: Mapping[str, LandmarkMap] = field(default_factory=dict)
    bound: np.ndarray | None = None


def belief_frame(beliefs: Mapping[str, Any], landmarks: Mapping[str, Any] | None = None,
                 bound: np.ndarray | None = None) -> BeliefFrame:
    """A :class:`BeliefFrame` from each filter's ``belief()`` (None or a Gaussian: nothing
    beyond the estimate) and SLAM filters' ``landmarks()``; particles subsampled now
    (:func:`shown_particles`), so a frame kept for an export stays small."""
    particles: dict[str, tuple[np.ndarray, int]] = {}
    grids: dict[str, GridBelief] = {}
    for name, bel in beliefs.items():
        if isinstance(bel, ParticleBelief):
            particles[name] = (shown_particles(bel.poses, bel.weights), len(bel.poses))
        elif isinstance(bel, GridBelief):
            grids[name] = GridBelief(np.asarray(bel.prob, dtype=np.float32).copy(),
                                     (float(bel.origin[0]), float(bel.origin[1])), float(bel.cell))
    maps = {n: lm for n, lm in (landmarks or {}).items() if isinstance(lm, LandmarkMap)}
    return BeliefFrame(particles, grids, maps, None if bound is None else np.asarray(bound, dtype=float))


def read_frame(tracks: Mapping[str, Any], bound: np.ndarray | None = None) -> BeliefFrame:
    """The :class:`BeliefFrame` of a runner's ``tracks`` now: each running filter's
    ``belief()`` and (SLAM) ``landmarks()``; a filter whose call raises shows nothing more
    this tick (the run itself decides whether it goes on)."""
    beliefs: dict[str, Any] = {}
    maps: dict[str, Any] = {}
    for name, tr in tracks.items():
        flt = getattr(tr, "filter", None)
        if flt is None or getattr(tr, "failed", None):
            continue
        try:
            beliefs[name] = flt.belief()
            if callable(getattr(flt, "landmarks", None)):
                maps[name] = flt.landmarks()
        except Exception:  # a student's belief(): the estimate still goes out
            continue
    return belief_frame(beliefs, maps, bound)


class Publisher:
    """The Foxglove topics of one run of ``scenario`` with ``filter_names``, logged on the
    foxglove ``context`` (whatever sinks it has: an MCAP writer, a WebSocket server).

    Call :meth:`start` once, then :meth:`tick` for each tick in order; a tick lower than the
    last (a replay sought back) starts the trails afresh.
    """

    def __init__(self, scenario: Scenario, filter_names: Sequence[str], context: Any):
        self.fox, self.ch, self.msg = foxglove_modules()
        self.scenario = scenario
        self.names = [str(n) for n in filter_names]
        self.context = context
        self.dt_ns = round(scenario.dt * 1e9)
        self.periods_ns = {s.name: round(s.period * 1e9) for s in scenario.sensors}
        self.beacons = {b.id: (b.x, b.y) for b in scenario.world.beacons}
        self.scanners = list(scan_sensors(scenario.sensors))
        self._channels: dict[str, Any] = {}
        self._trails: dict[str, list[tuple[float, float]]] = {}
        self._trail_start: dict[str, int] = {}
        self._last_tick = -1

    # -- channels ---------------------------------------------------------------------------
    def channel(self, topic: str, kind: str) -> Any:
        """The channel of ``topic``, created on first use: ``kind`` is a foxglove.channels
        name without ``Channel`` (``"SceneUpdate"``) or a key of :data:`JSON_SCHEMAS` (JSON)."""
        ch = self._channels.get(topic)
        if ch is None:
            if kind in JSON_SCHEMAS:
                ch = self.fox.Channel(topic, schema=JSON_SCHEMAS[kind], context=self.context)
            else:
                ch = getattr(self.ch, f"{kind}Channel")(topic, context=self.context)
            self._channels[topic] = ch
        return ch

    def declare(self, frame: BeliefFrame | None = None) -> None:
        """Create every topic's channel now (a live server advertises them before the first
        tick, so a client subscribes in time); an MCAP file creates them on first use.
        ``frame``: a first :class:`BeliefFrame`, for the particle, grid, map and bound topics
        it has."""
        for topic, kind in (("/world", "SceneUpdate"), ("/truth/pose", "PoseInFrame"),
                            ("/tf", "FrameTransform"), ("/truth/scene", "SceneUpdate"),
                            ("/trails", "SceneUpdate"), ("/readings", "SceneUpdate"), ("/events", "Log")):
            self.channel(topic, kind)
        if self.scenario.world.grid is not None:
            self.channel("/map", "Grid")
        for sensor in self.scanners:
            self.channel(f"/scan/{sensor}", "LaserScan")
        for name in self.names:
            self.channel(f"/filters/{name}/pose", "PoseInFrame")
            self.channel(f"/filters/{name}/scene", "SceneUpdate")
            self.channel(f"/filters/{name}/stats", "stats")
        if any(not is_scan(s.kind) for s in self.scenario.sensors):
            self.channel("/readings/values", "readings")
        if frame is not None:
            for name in frame.particles:
                self.channel(f"/filters/{name}/particles", "PosesInFrame")
            for name in frame.grids:
                self.channel(f"/filters/{name}/grid", "Grid")
            for name in frame.landmarks:
                self.channel(f"/filters/{name}/map", "SceneUpdate")
            if frame.bound is not None:
                self.channel("/pcrb", "SceneUpdate")
                self.channel("/pcrb/stats", "bound")

    @property
    def topics(self) -> list[str]:
        """The topics with a channel so far."""
        return list(self._channels)

    def close(self) -> None:
        for ch in self._channels.values():
            ch.close()
        self._channels.clear()

    # -- message parts ------------------------------------------------------------------------
    def _time(self, ns: int):
        return self.msg.Timestamp(ns // 1_000_000_000, ns % 1_000_000_000)

    def _quat(self, theta: float):
        """The rotation by ``theta`` [rad] about +z."""
        return self.msg.Quaternion(x=0.0, y=0.0, z=math.sin(theta / 2), w=math.cos(theta / 2))

    def _pose(self, x: float, y: float, theta: float = 0.0, z: float = 0.0):
        m = self.msg
        return m.Pose(position=m.Vector3(x=float(x), y=float(y), z=float(z)),
                      orientation=self._quat(float(theta)))

    def _colour(self, rgb: tuple[float, float, float], a: float = 1.0):
        return self.msg.Color(r=rgb[0], g=rgb[1], b=rgb[2], a=a)

    def _pt(self, x: float, y: float, z: float = 0.0):
        return self.msg.Point3(x=float(x), y=float(y), z=float(z))

    def _entity(self, ns: int, ident: str, lifetime_ns: int = 0, **prims):
        m = self.msg
        return m.SceneEntity(timestamp=self._time(ns), frame_id=FRAME, id=ident,
                             lifetime=m.Duration(lifetime_ns // 1_000_000_000, lifetime_ns % 1_000_000_000),
                             frame_locked=False, **prims)

    def _arrow(self, pose: np.ndarray, rgb: tuple[float, float, float], length: float):
        return self.msg.ArrowPrimitive(pose=self._pose(pose[0], pose[1], float(pose[2]), z=0.02),
                                       shaft_length=0.65 * length, shaft_diameter=0.06 * length,
                                       head_length=0.35 * length, head_diameter=0.18 * length,
                                       color=self._colour(rgb))

    # -- topics ---------------------------------------------------------------------------------
    def start(self, ns: int = 0) -> None:
        """``/world``: beacons as cylinders with their IDs, the world's bounds as a loop."""
        m = self.msg
        cyl, texts = [], []
        dark = self._colour(TRUTH_COLOUR)
        for b in self.scenario.world.beacons:
            cyl.append(m.CylinderPrimitive(pose=self._pose(b.x, b.y, z=0.15),
                                           size=m.Vector3(x=0.2, y=0.2, z=0.3),
                                           bottom_scale=1.0, top_scale=1.0, color=dark))
            texts.append(m.TextPrimitive(pose=self._pose(b.x, b.y, z=0.45), billboard=True,
                                         font_size=14.0, scale_invariant=True, color=dark, text=f"B{b.id}"))
        xmin, ymin, xmax, ymax = self.scenario.world.bounds
        loop = m.LinePrimitive(type=m.LinePrimitiveLineType.LineLoop, pose=self._pose(0, 0),
                               thickness=0.03, points=[self._pt(xmin, ymin), self._pt(xmax, ymin),
                                                       self._pt(xmax, ymax), self._pt(xmin, ymax)],
                               color=self._colour((0.4, 0.4, 0.4)))
        self.channel("/world", "SceneUpdate").log(m.SceneUpdate(entities=[
            self._entity(ns, "beacons", cylinders=cyl, texts=texts),
            self._entity(ns, "bounds", lines=[loop])]), log_time=ns)
        if self.scenario.world.grid is not None:
            self.channel("/map", "Grid").log(self._grid(ns, self.scenario.world.grid), log_time=ns)

    def _grid(self, ns: int, grid: Any):
        """The occupancy grid as a foxglove.Grid: row 0 (the bottom row, smallest y) first,
        one INT8 cell each (``FREE`` 0, ``OCCUPIED`` 100, ``UNKNOWN`` -1, as nav_msgs), the pose
        the world pose of cell (0, 0)'s lower-left corner (the map's origin, yaw included)."""
        m = self.msg
        cols = grid.cells.shape[1]
        ox, oy, yaw = grid.origin
        return m.Grid(timestamp=self._time(ns), frame_id=FRAME, pose=self._pose(ox, oy, yaw),
                      column_count=int(cols),
                      cell_size=m.Vector2(x=float(grid.resolution), y=float(grid.resolution)),
                      row_stride=int(cols), cell_stride=1,
                      fields=[m.PackedElementField(name="occupancy", offset=0,
                                                   type=m.PackedElementFieldNumericType.Int8)],
                      data=np.ascontiguousarray(grid.cells, dtype=np.int8).tobytes())

    def _laser_scan(self, ns: int, truth: np.ndarray, beams: Sequence[np.ndarray]):
        """One scan (rows ``[range, beam angle]`` [m, rad], beams evenly spaced) as a
        foxglove.LaserScan in frame ``world`` whose origin is the true pose: the bearings are
        relative to the robot's heading, counter-clockwise, first to last beam (the last one
        unwrapped past pi for a full circle)."""
        m = self.msg
        z = np.asarray(beams, dtype=float)
        ranges, angles = z[:, 0], z[:, 1]
        start = float(angles[0])
        end = start + float(np.sum(wrap(np.diff(angles)))) if len(angles) > 1 else start
        return m.LaserScan(timestamp=self._time(ns), frame_id=FRAME,
                           pose=self._pose(float(truth[0]), float(truth[1]), float(truth[2])),
                           start_angle=start, end_angle=end, ranges=[float(r) for r in ranges],
                           intensities=[])

    def tick(self, tick: int, truth: np.ndarray,
             estimates: Mapping[str, tuple[np.ndarray, np.ndarray] | None],
             readings: Sequence[tuple[str, str, np.ndarray, int]] = (),
             events: Sequence[tuple[str, str]] = (), frame: BeliefFrame | None = None) -> None:
        """One tick: the true pose [m, m, rad], each filter's ``(mean, cov)`` (None: no
        estimate this tick), the readings as ``(sensor, kind, z row, beacon id)``, the
        events as ``(kind, detail)`` and what the window draws beyond the estimates
        (``frame``: particles, grids, SLAM maps, the PCRB)."""
        frame = frame or BeliefFrame()
        m = self.msg
        ns = tick * self.dt_ns
        if tick <= self._last_tick:
            self._restart_trails(ns)
        self._last_tick = tick
        x, y, th = (float(v) for v in truth)
        self.channel("/truth/pose", "PoseInFrame").log(
            m.PoseInFrame(timestamp=self._time(ns), frame_id=FRAME, pose=self._pose(x, y, th)), log_time=ns)
        self.channel("/tf", "FrameTransform").log(m.FrameTransform(
            timestamp=self._time(ns), parent_frame_id=FRAME, child_frame_id=ROBOT_FRAME,
            translation=m.Vector3(x=x, y=y, z=0.0), rotation=self._quat(th)), log_time=ns)
        length = 2.0 * self.scenario.robot_radius
        self.channel("/truth/scene", "SceneUpdate").log(m.SceneUpdate(entities=[
            self._entity(ns, "truth/arrow", arrows=[self._arrow(truth, TRUTH_COLOUR, length)])]), log_time=ns)
        kidnapped = any(kind == "kidnap" for kind, _ in events)  # the truth's path jumps: cut it
        trail_entities = [self._trail("truth", ns, x, y, TRUTH_COLOUR, cut=kidnapped)]
        for i, name in enumerate(self.names):
            est = estimates.get(name)
            if est is None:
                continue
            mean, cov = np.asarray(est[0], dtype=float), np.asarray(est[1], dtype=float)
            if not np.all(np.isfinite(mean)):
                continue
            rgb = colour_of(i)
            self.channel(f"/filters/{name}/pose", "PoseInFrame").log(m.PoseInFrame(
                timestamp=self._time(ns), frame_id=FRAME, pose=self._pose(*mean)), log_time=ns)
            self.channel(f"/filters/{name}/scene", "SceneUpdate").log(
                m.SceneUpdate(entities=[self._estimate_entity(ns, name, mean, cov, rgb, length)]),
                log_time=ns)
            stats = {"timestamp": self._stamp(ns), "tick": int(tick), **filter_stats(mean, cov, truth)}
            if name in frame.particles:
                stats["particles_total"] = frame.particles[name][1]
                stats["particles_shown"] = len(frame.particles[name][0])
            self.channel(f"/filters/{name}/stats", "stats").log(stats, log_time=ns)
            trail_entities.append(self._trail(name, ns, mean[0], mean[1], rgb))
        self.channel("/trails", "SceneUpdate").log(m.SceneUpdate(entities=trail_entities), log_time=ns)
        scans: dict[str, list] = {}
        others = []
        for row in readings:
            if is_scan(row[1]):
                scans.setdefault(row[0], []).append(row[2])
            else:
                others.append(row)
        for sensor, beams in scans.items():
            self.channel(f"/scan/{sensor}", "LaserScan").log(self._laser_scan(ns, truth, beams), log_time=ns)
        if others:
            self.channel("/readings", "SceneUpdate").log(self._readings(ns, truth, others), log_time=ns)
            self.channel("/readings/values", "readings").log(self._reading_values(ns, tick, others),
                                                             log_time=ns)
        self._beliefs(ns, tick, truth, frame)
        for kind, detail in events:
            self.log_event(ns, "events", f"{kind}: {detail}" if detail else kind,
                           m.LogLevel.Warning if kind == "kidnap" else m.LogLevel.Info)

    def _stamp(self, ns: int) -> dict[str, int]:
        return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}

    def _reading_values(self, ns: int, tick: int, rows: Sequence[tuple[str, str, np.ndarray, int]]) -> dict:
        """``/readings/values``: each reading's numbers by name (the readings table's columns)."""
        out = []
        for sensor, kind, z, bid in rows:
            vals: dict[str, float | None] = dict.fromkeys(READING_FIELDS)
            record = sensor_kinds.KINDS.get(str(kind))
            for j, col in enumerate(record.columns if record is not None else ()):
                if col not in vals:  # a registered kind's own column: not in the schema
                    continue
                v = float(z[j])
                vals[col] = v if math.isfinite(v) else None
            out.append({"sensor": str(sensor), "kind": str(kind), "beacon_id": int(bid), **vals})
        return {"timestamp": self._stamp(ns), "tick": int(tick), "readings": out}

    def _beliefs(self, ns: int, tick: int, truth: np.ndarray, frame: BeliefFrame) -> None:
        """The particle clouds, grid beliefs, SLAM maps and the PCRB of one tick."""
        m = self.msg
        for name, (poses, _) in frame.particles.items():
            self.channel(f"/filters/{name}/particles", "PosesInFrame").log(m.PosesInFrame(
                timestamp=self._time(ns), frame_id=FRAME,
                poses=[self._pose(p[0], p[1], float(p[2])) for p in poses]), log_time=ns)
        for name, grid in frame.grids.items():
            self.channel(f"/filters/{name}/grid", "Grid").log(self._belief_grid(ns, grid), log_time=ns)
        for name, lm in frame.landmarks.items():
            i = self.names.index(name) if name in self.names else 0
            self.channel(f"/filters/{name}/map", "SceneUpdate").log(
                m.SceneUpdate(entities=[self._landmark_entity(ns, name, lm, colour_of(i))]), log_time=ns)
        if frame.bound is not None:
            P = np.asarray(frame.bound, dtype=float)
            ellipse = self._ellipse(float(truth[0]), float(truth[1]), P[:2, :2], BOUND_COLOUR, 0.25, z=0.005)
            self.channel("/pcrb", "SceneUpdate").log(m.SceneUpdate(entities=[
                self._entity(ns, "pcrb/ellipse", spheres=[ellipse])]), log_time=ns)
            with np.errstate(all="ignore"):
                pos = float(np.sqrt(max(float(np.linalg.eigvalsh(0.5 * (P[:2, :2] + P[:2, :2].T))[-1]), 0.0)))
            nums = {"sigma_x_m": math.sqrt(max(P[0, 0], 0.0)), "sigma_y_m": math.sqrt(max(P[1, 1], 0.0)),
                    "sigma_theta_rad": math.sqrt(max(P[2, 2], 0.0)), "sigma_pos_m": pos,
                    **{c: float(P[i, j]) for c, (i, j) in zip(COV_COLUMNS, UPPER, strict=True)}}
            self.channel("/pcrb/stats", "bound").log(
                {"timestamp": self._stamp(ns), "tick": int(tick),
                 **{k: (v if math.isfinite(v) else None) for k, v in nums.items()}}, log_time=ns)

    def _belief_grid(self, ns: int, grid: GridBelief):
        """A grid belief as a foxglove.Grid: one FLOAT32 cell ``probability`` each, rows along
        +y (row j = the cells ``[ymin + j cell, ...)``), columns along +x, the pose its corner."""
        m = self.msg
        prob = np.asarray(grid.prob, dtype="<f4")  # (nx, ny)
        nx = prob.shape[0]
        return m.Grid(timestamp=self._time(ns), frame_id=FRAME,
                      pose=self._pose(grid.origin[0], grid.origin[1], 0.0, z=-0.01), column_count=int(nx),
                      cell_size=m.Vector2(x=float(grid.cell), y=float(grid.cell)),
                      row_stride=int(nx) * 4, cell_stride=4,
                      fields=[m.PackedElementField(name="probability", offset=0,
                                                   type=m.PackedElementFieldNumericType.Float32)],
                      data=np.ascontiguousarray(prob.T).tobytes())

    def _ellipse(self, x: float, y: float, cov2: np.ndarray, rgb: tuple[float, float, float], alpha: float,
                 z: float = 0.0):
        """The 95 % ellipse of the x-y covariance ``cov2`` (2, 2) [m^2] at (x, y): a flat sphere."""
        m = self.msg
        with np.errstate(all="ignore"):
            vals, vecs = np.linalg.eigh(0.5 * (cov2 + cov2.T))
        vals = np.nan_to_num(np.clip(vals, 0.0, None))
        angle = math.atan2(vecs[1, 1], vecs[0, 1]) if np.all(np.isfinite(vecs)) else 0.0
        size = m.Vector3(x=2 * ELLIPSE_SCALE * math.sqrt(vals[1]), y=2 * ELLIPSE_SCALE * math.sqrt(vals[0]),
                         z=0.01)
        return m.SpherePrimitive(pose=self._pose(x, y, angle, z=z), size=size, color=self._colour(rgb, alpha))

    def _landmark_entity(self, ns: int, name: str, lm: LandmarkMap, rgb: tuple[float, float, float]):
        """A SLAM map: per landmark a small sphere at its mean, its 95 % ellipse and a label
        (``L<beacon id>``, or ``L<row>`` without IDs); each landmark's mean and covariance
        (``landmark_K`` -> ``id x y cov_xx cov_xy cov_yy``) in the metadata."""
        m = self.msg
        means = np.asarray(lm.means, dtype=float).reshape(-1, 2)
        covs = np.asarray(lm.covs, dtype=float).reshape(-1, 2, 2)
        ids = list(range(len(means))) if lm.ids is None else [int(v) for v in lm.ids]
        spheres, texts, meta = [], [], []
        for k, ((x, y), c) in enumerate(zip(means, covs, strict=True)):
            spheres.append(m.SpherePrimitive(pose=self._pose(x, y, z=0.1),
                                             size=m.Vector3(x=0.12, y=0.12, z=0.12), color=self._colour(rgb)))
            spheres.append(self._ellipse(float(x), float(y), c, rgb, 0.3, z=0.02))
            texts.append(m.TextPrimitive(pose=self._pose(x, y, z=0.3), billboard=True, font_size=12.0,
                                         scale_invariant=True, color=self._colour(rgb), text=f"L{ids[k]}"))
            meta.append(m.KeyValuePair(key=f"landmark_{k}", value=" ".join(
                [str(ids[k])] + [repr(float(v)) for v in (x, y, c[0, 0], c[0, 1], c[1, 1])])))
        return self._entity(ns, f"{name}/landmarks", metadata=meta, spheres=spheres, texts=texts)

    def log_event(self, ns: int, name: str, text: str, level: Any = None) -> None:
        m = self.msg
        self.channel("/events", "Log").log(m.Log(timestamp=self._time(ns), level=level or m.LogLevel.Info,
                                                 message=text, name=name), log_time=ns)

    def failed(self, tick: int, name: str, why: str) -> None:
        """``/events``: filter ``name`` was switched off at ``tick`` (an error-level log)."""
        self.log_event(tick * self.dt_ns, f"filters/{name}", f"{name} switched off: {why}",
                       self.msg.LogLevel.Error)

    def _estimate_entity(self, ns: int, name: str, mean: np.ndarray, cov: np.ndarray,
                         rgb: tuple[float, float, float], length: float):
        """The estimate as an arrow and its 95 % x-y ellipse (a flat sphere); the covariance
        (row-major, [m^2, m^2 rad, rad^2]) and the 2-sigma heading in the metadata."""
        m = self.msg
        meta = [m.KeyValuePair(key=f"cov_{a}{b}", value=repr(float(cov[i, j])))
                for i, a in enumerate("xyt") for j, b in enumerate("xyt")]
        meta.append(m.KeyValuePair(key="heading_2sigma_rad",
                                   value=repr(2 * math.sqrt(max(float(np.nan_to_num(cov[2, 2])), 0.0)))))
        ellipse = self._ellipse(float(mean[0]), float(mean[1]), cov[:2, :2], rgb, 0.35)
        return self._entity(ns, f"{name}/estimate", metadata=meta, spheres=[ellipse],
                            arrows=[self._arrow(mean, rgb, length)])

    def _trail(self, source: str, ns: int, x: float, y: float, rgb: tuple[float, float, float],
               cut: bool = False):
        """The current piece of ``source``'s path, with the new point: one entity per piece
        (``source/trail/K``), kept until deleted, so the whole path shows. A full piece is
        followed by one starting where it ended; ``cut`` (a kidnap) starts one afresh."""
        pts = self._trails.setdefault(source, [])
        if len(pts) >= TRAIL_PIECE or (cut and pts):
            self._trail_start[source] = self._trail_start.get(source, 0) + 1
            pts[:] = [] if cut else pts[-1:]
        pts.append((float(x), float(y)))
        m = self.msg
        line = m.LinePrimitive(type=m.LinePrimitiveLineType.LineStrip, pose=self._pose(0, 0),
                               thickness=0.03, points=[self._pt(px, py, 0.01) for px, py in pts],
                               color=self._colour(rgb, 0.8))
        return self._entity(ns, f"{source}/trail/{self._trail_start.get(source, 0)}", lines=[line])

    def _restart_trails(self, ns: int) -> None:
        m = self.msg
        self._trails.clear()
        self._trail_start.clear()
        self.channel("/trails", "SceneUpdate").log(m.SceneUpdate(deletions=[m.SceneEntityDeletion(
            timestamp=self._time(ns), type=m.SceneEntityDeletionType.All)]), log_time=ns)

    def _readings(self, ns: int, truth: np.ndarray, rows: Sequence[tuple[str, str, np.ndarray, int]]):
        """One tick's readings as rays from the true pose: range_bearing, the measured range
        along the measured bearing; bearing, along the bearing as far as the true beacon; a
        pose / position fix, a small sphere at the fix; a reading of another kind that names its
        beacon, a ray to that beacon. One entity per sensor, living one
        sensor period."""
        m = self.msg
        x, y, th = (float(v) for v in truth)
        by_sensor: dict[str, dict[str, list]] = {}
        for sensor, kind, z, bid in rows:
            prims = by_sensor.setdefault(sensor, {"points": [], "spheres": []})
            if kind in ("range_bearing", "bearing"):
                if kind == "range_bearing":
                    r, b = float(z[0]), float(z[1])
                else:
                    bx, by = self.beacons.get(bid, (x, y))
                    r, b = math.hypot(bx - x, by - y), float(z[0])
                prims["points"] += [self._pt(x, y, 0.05),
                                    self._pt(x + r * math.cos(th + b), y + r * math.sin(th + b), 0.05)]
            elif kind in ("pose", "position"):
                prims["spheres"].append(m.SpherePrimitive(pose=self._pose(z[0], z[1]),
                                                          size=m.Vector3(x=0.15, y=0.15, z=0.15),
                                                          color=self._colour(READING_COLOUR, 0.8)))
            elif names_beacons(kind) and bid in self.beacons:   # another kind: a ray to its beacon
                bx, by = self.beacons[bid]
                prims["points"] += [self._pt(x, y, 0.05), self._pt(bx, by, 0.05)]
        entities = []
        for sensor, prims in by_sensor.items():
            lines = [m.LinePrimitive(type=m.LinePrimitiveLineType.LineList, pose=self._pose(0, 0),
                                     thickness=0.02, points=prims["points"],
                                     color=self._colour(READING_COLOUR, 0.8))] if prims["points"] else []
            entities.append(self._entity(ns, f"readings/{sensor}", self.periods_ns.get(sensor, 0),
                                         lines=lines, spheres=prims["spheres"]))
        return m.SceneUpdate(entities=entities)


__all__ = [
    "BOUND_COLOUR",
    "BOUND_FIELDS",
    "BOUND_SCHEMA",
    "ELLIPSE_SCALE",
    "FILTER_COLOURS",
    "FRAME",
    "INSTALL_HINT",
    "JSON_SCHEMAS",
    "MAX_PARTICLES_SHOWN",
    "READINGS_SCHEMA",
    "READING_COLOUR",
    "READING_FIELDS",
    "ROBOT_FRAME",
    "STATS_FIELDS",
    "STATS_SCHEMA",
    "TRAIL_PIECE",
    "TRUTH_COLOUR",
    "BeliefFrame",
    "Publisher",
    "belief_frame",
    "colour_of",
    "filter_stats",
    "foxglove_modules",
    "layout",
    "read_frame",
    "shown_particles",
]
