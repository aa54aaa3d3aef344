"""A run as an MCAP file for Foxglove (``beacon-sim export FILE --out run.mcap``).

Fed with the arrays of :mod:`beacon_sim.io.export` (:func:`~beacon_sim.io.export.step_arrays`
and :func:`~beacon_sim.io.export.filter_arrays`), so the MCAP, ``.npz`` and ``.csv`` exports
hold the same numbers. Messages are JSON in Foxglove's well-known schemas, so Foxglove's 3D,
Log and Plot panels show them without any plug-in:

==============================  ======================  =========================================
topic                           schema                  one message
==============================  ======================  =========================================
``/world``                      foxglove.SceneUpdate    at t = 0: beacons (with ID labels), bounds
``/truth/pose``                 foxglove.PoseInFrame    per tick, t = 0 included
``/tf``                         foxglove.FrameTransform per tick: ``world`` -> ``robot`` (truth)
``/filters/NAME/pose``          foxglove.PoseInFrame    per tick with an estimate
``/filters/NAME/covariance``    foxglove.SceneUpdate    same ticks: the 95 % x-y ellipse; the
                                                        3 x 3 covariance in the entity's metadata
``/readings``                   foxglove.SceneUpdate    per tick with readings: rays from the
                                                        true pose, one entity per sensor, living
                                                        one sensor period
``/events``                     foxglove.Log            per event (kidnap, blackout, ...) and per
                                                        filter switched off
==============================  ======================  =========================================

Frame ``world`` is the simulation's world frame (x right, y up, metres; z = 0 is the floor);
a heading theta [rad] is the rotation about +z. Time stamps are simulated time: tick ``k`` is
at ``k * dt`` seconds after the epoch (Foxglove shows 1970-01-01), in nanoseconds, so every
topic shares one timeline. The ``mcap`` package is the optional ``mcap`` extra.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from beacon_sim.core.scenario import Scenario
from beacon_sim.io.tables import prefixed, reading_matrix

INSTALL_HINT = "MCAP export needs the mcap package: pip install 'beacon-sim[mcap]'"
FRAME = "world"
ROBOT_FRAME = "robot"
#: The 95 % x-y ellipse: sqrt of the chi-square quantile for 2 degrees of freedom.
ELLIPSE_SCALE = math.sqrt(-2.0 * math.log(0.05))
#: Filter colours (r, g, b) in channel order, repeated when there are more filters.
FILTER_COLOURS = ((0.12, 0.47, 0.71), (1.0, 0.5, 0.05), (0.17, 0.63, 0.17), (0.84, 0.15, 0.16),
                  (0.58, 0.4, 0.74), (0.55, 0.34, 0.29), (0.89, 0.47, 0.76), (0.5, 0.5, 0.5))
#: foxglove.Log levels.
LOG_INFO, LOG_WARNING, LOG_ERROR = 2, 3, 4


# -- JSON Schemas of the Foxglove message types used here (the fields this file writes) -----

def _obj(title: str, **props: dict) -> dict:
    return {"title": title, "type": "object", "properties": props}


_NUM: dict = {"type": "number"}
_INT: dict = {"type": "integer", "minimum": 0}
_STR: dict = {"type": "string"}
_TIME = _obj("time", sec=_INT, nsec=_INT)
_VEC3 = _obj("foxglove.Vector3", x=_NUM, y=_NUM, z=_NUM)
_QUAT = _obj("foxglove.Quaternion", x=_NUM, y=_NUM, z=_NUM, w=_NUM)
_COLOR = _obj("foxglove.Color", r=_NUM, g=_NUM, b=_NUM, a=_NUM)
_POSE = _obj("foxglove.Pose", position=_VEC3, orientation=_QUAT)
_KV = _obj("foxglove.KeyValuePair", key=_STR, value=_STR)


def _array(item: dict) -> dict:
    return {"type": "array", "items": item}


_SPHERE = _obj("foxglove.SpherePrimitive", pose=_POSE, size=_VEC3, color=_COLOR)
_CYLINDER = _obj("foxglove.CylinderPrimitive", pose=_POSE, size=_VEC3, bottom_scale=_NUM,
                 top_scale=_NUM, color=_COLOR)
_LINE = _obj("foxglove.LinePrimitive",
             type={"type": "integer", "enum": [0, 1, 2],
                   "description": "0 line strip, 1 line loop, 2 line list"},
             pose=_POSE, thickness=_NUM, scale_invariant={"type": "boolean"},
             points=_array(_VEC3), color=_COLOR, colors=_array(_COLOR),
             indices=_array(_INT))
_TEXT = _obj("foxglove.TextPrimitive", pose=_POSE, billboard={"type": "boolean"},
             font_size=_NUM, scale_invariant={"type": "boolean"}, color=_COLOR, text=_STR)
_ENTITY = _obj("foxglove.SceneEntity", timestamp=_TIME, frame_id=_STR, id=_STR,
               lifetime=_obj("duration", sec=_INT, nsec=_INT), frame_locked={"type": "boolean"},
               metadata=_array(_KV), spheres=_array(_SPHERE), cylinders=_array(_CYLINDER),
               lines=_array(_LINE), texts=_array(_TEXT))

SCHEMAS: dict[str, dict] = {
    "foxglove.PoseInFrame": _obj("foxglove.PoseInFrame", timestamp=_TIME, frame_id=_STR, pose=_POSE),
    "foxglove.FrameTransform": _obj("foxglove.FrameTransform", timestamp=_TIME, parent_frame_id=_STR,
                                    child_frame_id=_STR, translation=_VEC3, rotation=_QUAT),
    "foxglove.SceneUpdate": _obj("foxglove.SceneUpdate",
                                 deletions=_array(_obj("foxglove.SceneEntityDeletion",
                                                       timestamp=_TIME, type=_INT, id=_STR)),
                                 entities=_array(_ENTITY)),
    "foxglove.Log": _obj("foxglove.Log", timestamp=_TIME,
                         level={"type": "integer", "enum": [0, 1, 2, 3, 4, 5],
                                "description": "1 debug, 2 info, 3 warning, 4 error, 5 fatal"},
                         message=_STR, name=_STR, file=_STR, line=_INT),
}


# -- message builders ----------------------------------------------------------------------

def _time(ns: int) -> dict[str, int]:
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def _quat(theta: float) -> dict[str, float]:
    """A rotation by ``theta`` [rad] about +z."""
    return {"x": 0.0, "y": 0.0, "z": math.sin(theta / 2), "w": math.cos(theta / 2)}


def _pose(x: float, y: float, theta: float = 0.0, z: float = 0.0) -> dict:
    return {"position": {"x": float(x), "y": float(y), "z": float(z)}, "orientation": _quat(float(theta))}


def _colour(rgb: tuple[float, float, float], a: float = 1.0) -> dict[str, float]:
    return {"r": rgb[0], "g": rgb[1], "b": rgb[2], "a": a}


def _entity(ns: int, ident: str, lifetime_ns: int = 0, **prims: list) -> dict:
    ent: dict[str, Any] = {"timestamp": _time(ns), "frame_id": FRAME, "id": ident,
                           "lifetime": _time(lifetime_ns), "frame_locked": False, "metadata": [],
                           "spheres": [], "cylinders": [], "lines": [], "texts": []}
    ent.update(prims)
    return ent


def _pt(x: float, y: float, z: float = 0.0) -> dict[str, float]:
    return {"x": float(x), "y": float(y), "z": float(z)}


def _line(kind: int, points: list[dict], rgb: tuple[float, float, float], thickness: float,
          a: float = 1.0) -> dict:
    return {"type": kind, "pose": _pose(0.0, 0.0), "thickness": thickness, "scale_invariant": False,
            "points": points, "color": _colour(rgb, a), "colors": [], "indices": []}


def world_update(scenario: Scenario) -> dict:
    """The ``/world`` message: each beacon a cylinder with its ID, and the world's bounds."""
    cyl, texts = [], []
    for b in scenario.world.beacons:
        cyl.append({"pose": _pose(b.x, b.y, z=0.15), "size": _pt(0.2, 0.2, 0.3), "bottom_scale": 1.0,
                    "top_scale": 1.0, "color": _colour((0.1, 0.1, 0.1))})
        texts.append({"pose": _pose(b.x, b.y, z=0.45), "billboard": True, "font_size": 14.0,
                      "scale_invariant": True, "color": _colour((0.1, 0.1, 0.1)), "text": f"B{b.id}"})
    xmin, ymin, xmax, ymax = scenario.world.bounds
    bounds = _line(1, [_pt(xmin, ymin), _pt(xmax, ymin), _pt(xmax, ymax), _pt(xmin, ymax)],
                   (0.4, 0.4, 0.4), 0.03)
    return {"deletions": [], "entities": [
        _entity(0, "beacons", cylinders=cyl, texts=texts),
        _entity(0, "bounds", lines=[bounds])]}


def covariance_update(ns: int, name: str, mean: np.ndarray, cov: np.ndarray,
                      rgb: tuple[float, float, float]) -> dict:
    """The 95 % x-y ellipse of one estimate as a flat sphere, the covariance (row-major,
    [m^2, m^2 rad, rad^2]) and the 2-sigma heading in the metadata."""
    vals, vecs = np.linalg.eigh(0.5 * (cov[:2, :2] + cov[:2, :2].T))
    vals = np.clip(vals, 0.0, None)
    angle = math.atan2(vecs[1, 1], vecs[0, 1])  # direction of the major axis
    size = _pt(2 * ELLIPSE_SCALE * math.sqrt(vals[1]), 2 * ELLIPSE_SCALE * math.sqrt(vals[0]), 0.01)
    meta = [{"key": f"cov_{a}{b}", "value": repr(float(cov[i, j]))}
            for i, a in enumerate("xyt") for j, b in enumerate("xyt")]
    meta.append({"key": "heading_2sigma_rad", "value": repr(2 * math.sqrt(max(float(cov[2, 2]), 0.0)))})
    sphere = {"pose": _pose(mean[0], mean[1], angle), "size": size, "color": _colour(rgb, 0.35)}
    ent = _entity(ns, f"{name}/ellipse", spheres=[sphere])
    ent["metadata"] = meta
    return {"deletions": [], "entities": [ent]}


def readings_update(ns: int, pose: np.ndarray, rows: list[tuple[str, str, np.ndarray, int]],
                    scenario: Scenario, periods_ns: dict[str, int]) -> dict:
    """One tick's readings as rays from the true pose (``rows``: sensor, kind, z, beacon ID).

    range_bearing: a ray of the measured range along the measured bearing; bearing: a ray
    along the measured bearing as long as the true distance to the beacon; pose / position
    fix: a small sphere at the fix. Each sensor's entity lives one sensor period.
    """
    beacons = {b.id: (b.x, b.y) for b in scenario.world.beacons}
    by_sensor: dict[str, dict[str, list]] = {}
    x, y, th = (float(v) for v in pose)
    for sensor, kind, z, bid in rows:
        prims = by_sensor.setdefault(sensor, {"points": [], "spheres": []})
        if kind in ("range_bearing", "bearing"):
            if kind == "range_bearing":
                r, b = float(z[0]), float(z[1])
            else:
                bx, by = beacons.get(bid, (x, y))
                r, b = math.hypot(bx - x, by - y), float(z[0])
            end = _pt(x + r * math.cos(th + b), y + r * math.sin(th + b), 0.05)
            prims["points"] += [_pt(x, y, 0.05), end]
        else:
            prims["spheres"].append({"pose": _pose(z[0], z[1]), "size": _pt(0.15, 0.15, 0.15),
                                     "color": _colour((0.9, 0.6, 0.0), 0.8)})
    entities = []
    for sensor, prims in by_sensor.items():
        lines = [_line(2, prims["points"], (0.9, 0.6, 0.0), 0.02, 0.8)] if prims["points"] else []
        entities.append(_entity(ns, f"readings/{sensor}", periods_ns.get(sensor, 0), lines=lines,
                                spheres=prims["spheres"]))
    return {"deletions": [], "entities": entities}


def messages(scenario: Scenario, arrays: dict[str, np.ndarray]):
    """Every message as (topic, schema name, log time [ns], message dict), in time order
    within each topic."""
    dt_ns = round(scenario.dt * 1e9)
    truth = arrays["truth"]
    yield "/world", "foxglove.SceneUpdate", 0, world_update(scenario)
    for k, (x, y, th) in enumerate(truth):
        ns = k * dt_ns
        yield "/truth/pose", "foxglove.PoseInFrame", ns, {
            "timestamp": _time(ns), "frame_id": FRAME, "pose": _pose(x, y, th)}
        yield "/tf", "foxglove.FrameTransform", ns, {
            "timestamp": _time(ns), "parent_frame_id": FRAME, "child_frame_id": ROBOT_FRAME,
            "translation": _pt(x, y), "rotation": _quat(float(th))}
    names = [str(n) for n in arrays.get("filter_names", [])]
    for i, name in enumerate(names):
        rgb = FILTER_COLOURS[i % len(FILTER_COLOURS)]
        means, covs = arrays["est_mean"][i], arrays["est_cov"][i]
        last = 0
        for row in range(means.shape[0]):
            if np.isnan(means[row]).any():
                continue
            last = row + 1
            ns = (row + 1) * dt_ns
            yield f"/filters/{name}/pose", "foxglove.PoseInFrame", ns, {
                "timestamp": _time(ns), "frame_id": FRAME, "pose": _pose(*means[row])}
            yield f"/filters/{name}/covariance", "foxglove.SceneUpdate", ns, covariance_update(
                ns, name, means[row], covs[row], rgb)
        failed = str(arrays["filter_failed"][i])
        if failed:  # switched off after its last estimate (tick ``last``)
            ns = min(last + 1, len(truth) - 1) * dt_ns
            yield "/events", "foxglove.Log", ns, {
                "timestamp": _time(ns), "level": LOG_ERROR, "name": f"filters/{name}",
                "message": f"{name} switched off: {failed}", "file": "", "line": 0}
    periods = {s.name: round(s.period * 1e9) for s in scenario.sensors}
    readings = prefixed(arrays, "readings")
    z = reading_matrix(readings)
    mt = readings["tick"]
    for k in np.unique(mt):
        idx = np.flatnonzero(mt == k)
        rows = [(str(readings["sensor"][j]), str(readings["kind"][j]), z[j],
                 int(readings["beacon_id"][j])) for j in idx]
        ns = int(k) * dt_ns
        yield "/readings", "foxglove.SceneUpdate", ns, readings_update(ns, truth[k], rows, scenario, periods)
    for j in range(len(arrays["events_tick"])):
        ns = int(arrays["events_tick"][j]) * dt_ns
        kind, detail = str(arrays["events_kind"][j]), str(arrays["events_detail"][j])
        yield "/events", "foxglove.Log", ns, {
            "timestamp": _time(ns), "level": LOG_WARNING if kind == "kidnap" else LOG_INFO,
            "name": "events", "message": f"{kind}: {detail}" if detail else kind, "file": "", "line": 0}


def write_mcap(path: Path | str, scenario: Scenario, arrays: dict[str, np.ndarray],
               metadata: dict[str, str] | None = None) -> Path:
    """Write the run in ``arrays`` (step arrays, plus filter arrays when filters ran) to an
    MCAP file at ``path``; ``metadata`` goes into a ``beacon-sim`` metadata record. Messages
    are written in time order (ties: in the order of the table above). Returns the path."""
    try:
        from mcap.writer import CompressionType, Writer
    except ImportError as exc:
        raise ImportError(INSTALL_HINT) from exc
    from beacon_sim.version import __version__

    path = Path(path)
    msgs = sorted(messages(scenario, arrays), key=lambda m: m[2])  # stable: ties keep their order
    with path.open("wb") as f:
        w = Writer(f, compression=CompressionType.ZSTD)
        w.start(profile="", library=f"beacon-sim {__version__}")
        schema_ids = {name: w.register_schema(name=name, encoding="jsonschema",
                                              data=json.dumps(s).encode()) for name, s in SCHEMAS.items()}
        channels: dict[str, int] = {}
        seq: dict[str, int] = {}
        for topic, schema, ns, msg in msgs:
            if topic not in channels:
                channels[topic] = w.register_channel(topic=topic, message_encoding="json",
                                                     schema_id=schema_ids[schema])
                seq[topic] = 0
            w.add_message(channels[topic], log_time=ns, publish_time=ns, sequence=seq[topic],
                          data=json.dumps(msg, separators=(",", ":")).encode())
            seq[topic] += 1
        meta = {"scenario": scenario.name, "dt_s": repr(scenario.dt)}
        meta.update(metadata or {})
        w.add_metadata("beacon-sim", {k: str(v) for k, v in meta.items()})
        w.finish()
    return path
