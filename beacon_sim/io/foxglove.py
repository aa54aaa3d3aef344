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
``/filters/NAME/stats``          beacon_sim.FilterStats      same ticks: error, sigma, NEES (JSON;
                                                             for the Plot panel)
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
===============================  ==========================  ======================================

Frame ``world`` is the simulation's world frame (x right, y up, metres; z = 0 the floor); a
heading theta [rad] is the rotation about +z. Time stamps are simulated time: tick ``k`` is
``k * dt`` seconds after the epoch (Foxglove shows 1970-01-01), in nanoseconds. The numbers of
``/filters/NAME/stats`` are those of the ``estimates`` table (:mod:`beacon_sim.io.tables`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.metrics import pose_errors
from beacon_sim.core.scenario import Scenario
from beacon_sim.core.sensor_kinds import names_beacons

INSTALL_HINT = "Foxglove output needs the foxglove-sdk package: pip install 'beacon-sim[mcap]'"
FRAME = "world"
ROBOT_FRAME = "robot"
#: The 95 % x-y ellipse: sqrt of the chi-square quantile for 2 degrees of freedom.
ELLIPSE_SCALE = math.sqrt(-2.0 * math.log(0.05))
TRUTH_COLOUR = (0.1, 0.1, 0.1)
#: Filter colours (r, g, b), in the filters' order, repeated when there are more filters.
FILTER_COLOURS = ((0.12, 0.47, 0.71), (1.0, 0.5, 0.05), (0.17, 0.63, 0.17), (0.84, 0.15, 0.16),
                  (0.58, 0.4, 0.74), (0.55, 0.34, 0.29), (0.89, 0.47, 0.76), (0.5, 0.5, 0.5))
READING_COLOUR = (0.9, 0.6, 0.0)
#: Points of one trail entity: a path is sent in pieces of this many ticks, so each tick's
#: message stays small (only the last piece changes).
TRAIL_PIECE = 50
#: The numbers of ``/filters/NAME/stats`` (beacon_sim.FilterStats), with their units.
STATS_FIELDS = ("err_x_m", "err_y_m", "err_theta_rad", "err_pos_m", "sigma_x_m", "sigma_y_m",
                "sigma_theta_rad", "nees")
STATS_SCHEMA: dict[str, Any] = {
    "title": "beacon_sim.FilterStats", "type": "object",
    "description": "A filter's estimate against the truth at one tick: error (estimate - truth, "
                   "heading wrapped), standard deviations from its covariance, NEES (e^T P^-1 e; "
                   "null when P is singular)",
    "properties": {
        "timestamp": {"type": "object", "properties": {"sec": {"type": "integer", "minimum": 0},
                                                       "nsec": {"type": "integer", "minimum": 0}},
                      "required": ["sec", "nsec"]},
        "tick": {"type": "integer", "minimum": 0},
        **{f: {"type": ["number", "null"]} for f in STATS_FIELDS},
    },
    "required": ["timestamp", "tick", *STATS_FIELDS],
}


def foxglove_modules():
    """``(foxglove, foxglove.channels, foxglove.messages)``, or ImportError with the hint."""
    try:
        import foxglove
        from foxglove import channels, messages
    except ImportError as exc:
        raise ImportError(INSTALL_HINT) from exc
    return foxglove, channels, messages


def colour_of(index: int) -> tuple[float, float, float]:
    return FILTER_COLOURS[index % len(FILTER_COLOURS)]


def filter_stats(mean: np.ndarray, cov: np.ndarray, truth: np.ndarray) -> dict[str, float | None]:
    """Error [m, m, rad], sigma [m, m, rad] and NEES of one estimate, as the ``estimates``
    table computes them (the same operations, so the same bits)."""
    err = pose_errors(np.asarray(mean, dtype=float)[None], np.asarray(truth, dtype=float)[None])[0]
    with np.errstate(all="ignore"):
        try:
            nees: float | None = float(err @ np.linalg.solve(cov, err))
        except np.linalg.LinAlgError:
            nees = None
        sig = np.sqrt(np.diag(cov))
    out: dict[str, float | None] = {"err_x_m": float(err[0]), "err_y_m": float(err[1]),
                                    "err_theta_rad": float(err[2]),
                                    "err_pos_m": float(np.hypot(err[0], err[1]))}
    out.update({"sigma_x_m": float(sig[0]), "sigma_y_m": float(sig[1]), "sigma_theta_rad": float(sig[2]),
                "nees": nees})
    return {k: (v if v is None or math.isfinite(v) else None) for k, v in out.items()}


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
        self.scanners = [s.name for s in scenario.sensors if s.kind == "range_finder"]
        self._channels: dict[str, Any] = {}
        self._trails: dict[str, list[tuple[float, float]]] = {}
        self._trail_start: dict[str, int] = {}
        self._last_tick = -1

    # -- channels ---------------------------------------------------------------------------
    def channel(self, topic: str, kind: str) -> Any:
        """The channel of ``topic``, created on first use: ``kind`` is a foxglove.channels
        name without ``Channel`` (``"SceneUpdate"``) or ``"stats"`` (JSON)."""
        ch = self._channels.get(topic)
        if ch is None:
            if kind == "stats":
                ch = self.fox.Channel(topic, schema=STATS_SCHEMA, context=self.context)
            else:
                ch = getattr(self.ch, f"{kind}Channel")(topic, context=self.context)
            self._channels[topic] = ch
        return ch

    def declare(self) -> None:
        """Create every topic's channel now (a live server advertises them before the first
        tick, so a client subscribes in time); an MCAP file creates them on first use."""
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
             events: Sequence[tuple[str, str]] = ()) -> None:
        """One tick: the true pose [m, m, rad], each filter's ``(mean, cov)`` (None: no
        estimate this tick), the readings as ``(sensor, kind, z row, beacon id)`` and the
        events as ``(kind, detail)``."""
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
            self.channel(f"/filters/{name}/stats", "stats").log(
                {"timestamp": {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}, "tick": int(tick),
                 **filter_stats(mean, cov, truth)}, log_time=ns)
            trail_entities.append(self._trail(name, ns, mean[0], mean[1], rgb))
        self.channel("/trails", "SceneUpdate").log(m.SceneUpdate(entities=trail_entities), log_time=ns)
        scans: dict[str, list] = {}
        others = []
        for row in readings:
            if row[1] == "range_finder":
                scans.setdefault(row[0], []).append(row[2])
            else:
                others.append(row)
        for sensor, beams in scans.items():
            self.channel(f"/scan/{sensor}", "LaserScan").log(self._laser_scan(ns, truth, beams), log_time=ns)
        if others:
            self.channel("/readings", "SceneUpdate").log(self._readings(ns, truth, others), log_time=ns)
        for kind, detail in events:
            self.log_event(ns, "events", f"{kind}: {detail}" if detail else kind,
                           m.LogLevel.Warning if kind == "kidnap" else m.LogLevel.Info)

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
        with np.errstate(all="ignore"):
            vals, vecs = np.linalg.eigh(0.5 * (cov[:2, :2] + cov[:2, :2].T))
        vals = np.nan_to_num(np.clip(vals, 0.0, None))
        angle = math.atan2(vecs[1, 1], vecs[0, 1]) if np.all(np.isfinite(vecs)) else 0.0
        size = m.Vector3(x=2 * ELLIPSE_SCALE * math.sqrt(vals[1]), y=2 * ELLIPSE_SCALE * math.sqrt(vals[0]),
                         z=0.01)
        meta = [m.KeyValuePair(key=f"cov_{a}{b}", value=repr(float(cov[i, j])))
                for i, a in enumerate("xyt") for j, b in enumerate("xyt")]
        meta.append(m.KeyValuePair(key="heading_2sigma_rad",
                                   value=repr(2 * math.sqrt(max(float(np.nan_to_num(cov[2, 2])), 0.0)))))
        ellipse = m.SpherePrimitive(pose=self._pose(mean[0], mean[1], angle), size=size,
                                    color=self._colour(rgb, 0.35))
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
