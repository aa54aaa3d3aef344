"""A run as a ROS 2 bag (``beacon-sim export FILE --out run.mcap --ros2``, or ``run.db3``),
written with ``rosbags`` (pure Python, the ``ros`` extra): no ROS installation needed.

The bag is rosbag2's own layout, a folder ``run/`` holding ``metadata.yaml`` and
``run.mcap`` (MCAP storage) or ``run.db3`` (SQLite 3 storage), bag format version 8 (ROS 2
Jazzy and later read it; ``ros2 bag play run``). Standard messages only, in the frames of
REP 105:

===============================  ======================================  ===========================
topic                            type                                    one message
===============================  ======================================  ===========================
``/tf``                          tf2_msgs/msg/TFMessage                  per tick: ``map -> odom``
                                                                         and ``odom -> base_link``
``/odom``                        nav_msgs/msg/Odometry                   per tick: dead reckoning of
                                                                         the command in ``odom``
``/truth``                       nav_msgs/msg/Odometry                   per tick: the true pose in
                                                                         ``map``, the command as twist
``/filters/NAME/pose``           geometry_msgs/msg/                      per tick with an estimate:
                                 PoseWithCovarianceStamped               mean and covariance in ``map``
``/map``                         nav_msgs/msg/OccupancyGrid              once, in a map world
                                                                         (transient local, as
                                                                         map_server's)
``/beacons``                     visualization_msgs/msg/MarkerArray      once: the beacons (transient
                                                                         local)
``/scan/SENSOR``                 sensor_msgs/msg/LaserScan               per scan of range finder
                                                                         SENSOR, in ``base_link``
===============================  ======================================  ===========================

Frames: ``map`` is the simulation's world frame (x right, y up, metres); ``base_link`` the
robot (x forward); ``odom`` starts at the robot's initial pose and drifts as dead reckoning
does (the velocity model over the command ``v``, ``omega``); ``map -> odom`` is what makes
``map -> base_link`` the true pose. A heading theta is the rotation about +z, quaternion
``(0, 0, sin(theta/2), cos(theta/2))``. A 6 x 6 covariance is over (x, y, z, roll, pitch,
yaw), row-major: the filter's x, y, theta go to indices 0, 1, 5, the rest are 0. Stamps are
simulated time: tick ``k`` at ``k * dt`` seconds (play with ``--clock``, RViz with
``use_sim_time``).
"""

from __future__ import annotations

import math
import os
import secrets
import shutil
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.motion import move
from beacon_sim.core.optional import install_hint
from beacon_sim.core.raycast import beam_angles
from beacon_sim.core.scenario import Scenario
from beacon_sim.core.sensor_kinds import scan_sensors
from beacon_sim.errors import BeaconSimError
from beacon_sim.io.tables import prefixed, reading_matrix, upgrade_arrays

INSTALL_HINT = install_hint("rosbags")
#: Storage by the ``--out`` suffix: rosbags' storage plugins.
STORAGES = {".mcap": "MCAP", ".db3": "SQLITE3"}
MAP_FRAME, ODOM_FRAME, BASE_FRAME = "map", "odom", "base_link"
#: rosbag2 metadata version written (8: ROS 2 Jazzy's).
BAG_VERSION = 8
#: The 6 x 6 covariance indices of the filters' x, y, theta.
COV_INDEX = (0, 1, 5)


def rosbags_modules():
    """``(rosbags.rosbag2, rosbags.typesys, rosbags.interfaces)``, or ImportError with the hint."""
    try:
        from rosbags import interfaces, rosbag2, typesys
    except ImportError as exc:
        raise ImportError(INSTALL_HINT) from exc
    return rosbag2, typesys, interfaces


def typestore():
    """The ROS 2 message types the bag is written (and read back) with: ROS 2 Jazzy's."""
    _, typesys, _ = rosbags_modules()
    return typesys.get_typestore(typesys.Stores.ROS2_JAZZY)


def bag_folder(out: Path | str) -> Path:
    """The bag folder an ``--out`` name makes: ``run.mcap`` -> ``run/`` (its storage file is
    ``run/run.mcap``)."""
    out = Path(out)
    return out.with_suffix("")


def storage_file(out: Path | str) -> Path:
    """The storage file inside the bag folder: ``run/run.mcap`` or ``run/run.db3``."""
    out = Path(out)
    return bag_folder(out) / out.name


def dead_reckoning(control: np.ndarray, dt: float) -> np.ndarray:
    """The velocity model over the commands ``control`` (T, 2) [m/s, rad/s] from the pose
    (0, 0, 0): the ``odom -> base_link`` poses (T+1, 3) [m, m, rad], heading wrapped."""
    control = np.asarray(control, dtype=float).reshape(-1, 2)
    out = np.zeros((len(control) + 1, 3))
    for k, (v, w) in enumerate(control, start=1):
        out[k] = move(out[k - 1], float(v), float(w), dt)
    return out


def map_to_odom(truth: np.ndarray, odom: np.ndarray) -> np.ndarray:
    """The ``map -> odom`` poses (N, 3) that make ``map -> odom -> base_link`` the ``truth``
    (N, 3), given ``odom -> base_link`` poses ``odom`` (N, 3): truth composed with odom's
    inverse."""
    truth, odom = np.asarray(truth, dtype=float), np.asarray(odom, dtype=float)
    th = truth[:, 2] - odom[:, 2]
    c, s = np.cos(th), np.sin(th)
    x = truth[:, 0] - (c * odom[:, 0] - s * odom[:, 1])
    y = truth[:, 1] - (s * odom[:, 0] + c * odom[:, 1])
    return np.column_stack([x, y, wrap(th)])


def cov6(cov: np.ndarray) -> np.ndarray:
    """A 3 x 3 covariance over x, y, theta as ROS' 6 x 6 (x, y, z, roll, pitch, yaw), flat (36,):
    its upper triangle mirrored (the numbers of the ``estimates`` table's ``cov_*`` columns;
    a particle cloud's covariance may differ from symmetric in the last bit)."""
    c = np.triu(np.asarray(cov, dtype=float))
    c = c + np.triu(c, 1).T
    out = np.zeros((6, 6))
    out[np.ix_(COV_INDEX, COV_INDEX)] = c
    return out.reshape(36)


class _Messages:
    """Builds ROS 2 messages from the typestore's classes."""

    def __init__(self, store: Any):
        self.t = store.types

    def stamp(self, ns: int):
        return self.t["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)

    def header(self, ns: int, frame: str):
        return self.t["std_msgs/msg/Header"](stamp=self.stamp(ns), frame_id=frame)

    def pose(self, x: float, y: float, theta: float):
        t = self.t
        return t["geometry_msgs/msg/Pose"](
            position=t["geometry_msgs/msg/Point"](x=float(x), y=float(y), z=0.0),
            orientation=self.quat(theta))

    def quat(self, theta: float):
        return self.t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(float(theta) / 2),
                                                      w=math.cos(float(theta) / 2))

    def transform(self, ns: int, parent: str, child: str, pose: np.ndarray):
        t = self.t
        return t["geometry_msgs/msg/TransformStamped"](
            header=self.header(ns, parent), child_frame_id=child,
            transform=t["geometry_msgs/msg/Transform"](
                translation=t["geometry_msgs/msg/Vector3"](x=float(pose[0]), y=float(pose[1]), z=0.0),
                rotation=self.quat(float(pose[2]))))

    def odometry(self, ns: int, frame: str, pose: np.ndarray, v: float, omega: float):
        t = self.t
        zero = np.zeros(36)
        vec = t["geometry_msgs/msg/Vector3"]
        twist = t["geometry_msgs/msg/Twist"](linear=vec(x=float(v), y=0.0, z=0.0),
                                             angular=vec(x=0.0, y=0.0, z=float(omega)))
        return t["nav_msgs/msg/Odometry"](
            header=self.header(ns, frame), child_frame_id=BASE_FRAME,
            pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=self.pose(*pose), covariance=zero),
            twist=t["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=zero.copy()))


def write_ros2_bag(out: Path | str, scenario: Scenario, arrays: Mapping[str, np.ndarray],
                   metadata: Mapping[str, str] | None = None) -> Path:
    """Write the run in ``arrays`` (step arrays, plus filter arrays when filters ran) as a ROS 2
    bag for the ``--out`` name ``out`` (``run.mcap`` or ``run.db3``: :func:`bag_folder`); an
    existing bag folder of that name is replaced only once the new one is whole. ``metadata``
    goes into the bag's ``custom_data``. Returns the bag folder."""
    out = Path(out)
    if out.suffix not in STORAGES:
        raise BeaconSimError(f"{out}: expected a .mcap or .db3 name for a ROS 2 bag")
    rosbag2, _, _ = rosbags_modules()
    folder = bag_folder(out)
    staging = folder.parent / f".{folder.name}.{secrets.token_hex(4)}.tmp"
    try:
        staging.mkdir()
        _write(rosbag2, staging / folder.name, out.suffix, scenario, upgrade_arrays(arrays), metadata)
        old = None
        if folder.exists():
            if not (folder / "metadata.yaml").is_file():
                raise BeaconSimError(f"{folder}: exists and is not a ROS 2 bag; not replaced")
            old = folder.parent / f".{folder.name}.{secrets.token_hex(4)}.old"
            os.replace(folder, old)
        os.replace(staging / folder.name, folder)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except OSError as exc:
        raise BeaconSimError(f"{folder}: cannot write the ROS 2 bag: {exc.strerror or exc} "
                             "(the previous bag, if any, is unchanged)") from None
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return folder


def _qos(interfaces: Any, latched: bool) -> list:
    """The offered QoS of a topic: reliable, keep last 1; transient local when ``latched``
    (a map or the beacons, seen by a subscriber that comes late, as map_server offers)."""
    q = interfaces
    zero = q.QosTime(sec=0, nsec=0)
    return [q.Qos(history=q.QosHistory.KEEP_LAST, depth=1, reliability=q.QosReliability.RELIABLE,
                  durability=q.QosDurability.TRANSIENT_LOCAL if latched else q.QosDurability.VOLATILE,
                  deadline=zero, lifespan=zero, liveliness=q.QosLiveliness.AUTOMATIC,
                  liveliness_lease_duration=zero, avoid_ros_namespace_conventions=False)]


def _write(rosbag2: Any, path: Path, suffix: str, scenario: Scenario, a: Mapping[str, np.ndarray],
           metadata: Mapping[str, str] | None) -> None:
    from beacon_sim.version import __version__

    _, _, interfaces = rosbags_modules()
    store = typestore()
    msg = _Messages(store)
    t = store.types
    writer = rosbag2.Writer(path, version=BAG_VERSION,
                            storage_plugin=getattr(rosbag2.StoragePlugin, STORAGES[suffix]))
    meta = {"scenario": scenario.name, "dt_s": repr(scenario.dt), "library": f"beacon-sim {__version__}"}
    meta.update({k: str(v) for k, v in (metadata or {}).items()})
    for key, value in meta.items():
        writer.set_custom_data(f"beacon-sim.{key}", value)
    writer.open()
    conns: dict[str, Any] = {}

    def put(topic: str, kind: str, message: Any, ns: int, latched: bool = False) -> None:
        conn = conns.get(topic)
        if conn is None:
            conn = conns[topic] = writer.add_connection(topic, kind, typestore=store,
                                                        offered_qos_profiles=_qos(interfaces, latched))
        writer.write(conn, ns, store.serialize_cdr(message, kind))

    try:
        dt_ns = round(scenario.dt * 1e9)
        truth = np.asarray(a["truth"], dtype=float)
        control = np.asarray(a["control"], dtype=float).reshape(-1, 2)
        odom = dead_reckoning(control, scenario.dt)
        correction = map_to_odom(truth, odom)
        names = [str(n) for n in a.get("filter_names", [])]
        _beacons(put, msg, t, scenario)
        if scenario.world.grid is not None:
            put("/map", "nav_msgs/msg/OccupancyGrid", _occupancy(msg, t, scenario.world.grid), 0,
                latched=True)
        scans = _scans(a, scenario)
        for k in range(len(truth)):
            ns = k * dt_ns
            v, w = (control[k - 1] if k >= 1 else (0.0, 0.0))
            put("/tf", "tf2_msgs/msg/TFMessage", t["tf2_msgs/msg/TFMessage"](transforms=[
                msg.transform(ns, MAP_FRAME, ODOM_FRAME, correction[k]),
                msg.transform(ns, ODOM_FRAME, BASE_FRAME, odom[k])]), ns)
            put("/odom", "nav_msgs/msg/Odometry", msg.odometry(ns, ODOM_FRAME, odom[k], v, w), ns)
            put("/truth", "nav_msgs/msg/Odometry", msg.odometry(ns, MAP_FRAME, truth[k], v, w), ns)
            for i, name in enumerate(names):
                if k == 0:
                    continue
                mean = np.asarray(a["est_mean"][i][k - 1], dtype=float)
                if np.isnan(mean).all():
                    continue
                put(f"/filters/{name}/pose", "geometry_msgs/msg/PoseWithCovarianceStamped",
                    t["geometry_msgs/msg/PoseWithCovarianceStamped"](
                        header=msg.header(ns, MAP_FRAME),
                        pose=t["geometry_msgs/msg/PoseWithCovariance"](
                            pose=msg.pose(*mean), covariance=cov6(a["est_cov"][i][k - 1]))), ns)
            for sensor, z in scans.get(k, ()):
                put(f"/scan/{sensor}", "sensor_msgs/msg/LaserScan",
                    _laser_scan(msg, t, ns, scenario, sensor, z), ns)
    except BaseException:
        writer.close()
        raise
    writer.close()


def _scans(a: Mapping[str, np.ndarray], scenario: Scenario) -> dict[int, list[tuple[str, np.ndarray]]]:
    """Each tick's range finder scans: ``tick -> [(sensor, rows [range, bearing])]``."""
    readings = prefixed(a, "readings")
    z = reading_matrix(readings)
    scanners = set(scan_sensors(scenario.sensors))
    rows: dict[tuple[int, str], list[np.ndarray]] = {}
    for j, (k, sensor) in enumerate(zip(readings["tick"], readings["sensor"], strict=True)):
        if str(sensor) in scanners:
            rows.setdefault((int(k), str(sensor)), []).append(z[j, :2])
    out: dict[int, list[tuple[str, np.ndarray]]] = {}
    for (k, sensor), beams in rows.items():
        out.setdefault(k, []).append((sensor, np.array(beams)))
    return out


def _laser_scan(msg: _Messages, t: Any, ns: int, scenario: Scenario, sensor: str, z: np.ndarray):
    """One scan (rows ``[range, bearing]`` [m, rad]) in ``base_link``: the sensor's beams
    (:func:`beacon_sim.core.raycast.beam_angles`, counter-clockwise from ``angle_min``), each
    reading at its beam's index, NaN for a beam without one; ranges as float32 (ROS' type)."""
    spec = next(s for s in scenario.sensors if s.name == sensor)
    beams = beam_angles(spec.n_beams, spec.fov)
    n = len(beams)
    if n == 1:
        step = 0.0
    elif spec.fov >= 2 * math.pi:
        step = 2 * math.pi / n
    else:
        step = spec.fov / (n - 1)
    ranges = np.full(n, np.nan, dtype=np.float32)
    # each reading's beam: the nearest beam angle (the readings carry the beams' own angles)
    index = np.argmin(np.abs(wrap(beams[None, :] - np.asarray(z[:, 1], dtype=float)[:, None])), axis=1)
    ranges[index] = np.asarray(z[:, 0], dtype=np.float32)
    return t["sensor_msgs/msg/LaserScan"](
        header=msg.header(ns, BASE_FRAME), angle_min=float(beams[0]),
        angle_max=float(beams[0]) + step * (n - 1), angle_increment=step, time_increment=0.0,
        scan_time=float(spec.period), range_min=0.0, range_max=float(spec.max_range), ranges=ranges,
        intensities=np.zeros(0, dtype=np.float32))


def _occupancy(msg: _Messages, t: Any, grid: Any):
    """The occupancy grid as nav_msgs: row 0 the bottom row, 0 free, 100 occupied, -1 unknown
    (the same cell values as the simulation's), origin the lower-left corner of cell (0, 0)."""
    rows, cols = grid.cells.shape
    ox, oy, yaw = grid.origin
    return t["nav_msgs/msg/OccupancyGrid"](
        header=msg.header(0, MAP_FRAME),
        info=t["nav_msgs/msg/MapMetaData"](map_load_time=msg.stamp(0), resolution=float(grid.resolution),
                                           width=int(cols), height=int(rows), origin=msg.pose(ox, oy, yaw)),
        data=np.ascontiguousarray(grid.cells, dtype=np.int8).reshape(-1))


def _beacons(put: Any, msg: _Messages, t: Any, scenario: Scenario) -> None:
    """The beacons as cylinder markers (``id`` the beacon's ID) on ``/beacons``, in ``map``."""
    markers = []
    for b in scenario.world.beacons:
        markers.append(t["visualization_msgs/msg/Marker"](
            header=msg.header(0, MAP_FRAME), ns="beacons", id=int(b.id), type=3, action=0,
            pose=msg.pose(b.x, b.y, 0.0),
            scale=t["geometry_msgs/msg/Vector3"](x=0.2, y=0.2, z=0.3),
            color=t["std_msgs/msg/ColorRGBA"](r=0.1, g=0.1, b=0.1, a=1.0),
            lifetime=t["builtin_interfaces/msg/Duration"](sec=0, nanosec=0), frame_locked=False,
            points=[], colors=[], texture_resource="",
            texture=t["sensor_msgs/msg/CompressedImage"](header=msg.header(0, ""), format="",
                                                         data=np.zeros(0, dtype=np.uint8)),
            uv_coordinates=[], text="", mesh_resource="",
            mesh_file=t["visualization_msgs/msg/MeshFile"](filename="", data=np.zeros(0, dtype=np.uint8)),
            mesh_use_embedded_materials=False))
    if markers:
        put("/beacons", "visualization_msgs/msg/MarkerArray",
            t["visualization_msgs/msg/MarkerArray"](markers=markers), 0, latched=True)
