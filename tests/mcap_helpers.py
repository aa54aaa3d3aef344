"""Reading an MCAP file back with the schemas it carries, for the MCAP and Foxglove tests."""

from __future__ import annotations

import math

from foxglove_client import Decoder
from mcap.reader import make_reader

FOXGLOVE = {"foxglove.PoseInFrame", "foxglove.FrameTransform", "foxglove.SceneUpdate", "foxglove.Log"}


def read(path, topics=None):
    """(summary, {topic: [(log_time, schema name, decoded message, publish_time)]}): every
    message (of ``topics``, default all) decoded with its channel's schema (raises on one that
    does not decode)."""
    dec = Decoder()
    with path.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        by_topic: dict[str, list] = {}
        for schema, channel, message in reader.iter_messages(topics=topics, log_time_order=False):
            msg = dec.decode(schema.name, schema.encoding, schema.data, message.data)
            by_topic.setdefault(channel.topic, []).append((message.log_time, schema.name, msg,
                                                           message.publish_time))
    return summary, by_topic


def stamp_ns(stamp) -> int:
    """A decoded timestamp (protobuf JSON: an RFC 3339 string; ours: sec / nsec) [ns]."""
    if isinstance(stamp, dict):
        return stamp["sec"] * 1_000_000_000 + stamp["nsec"]
    from datetime import datetime

    whole, _, frac = stamp.rstrip("Z").partition(".")
    secs = int(datetime.fromisoformat(whole + "+00:00").timestamp())
    return secs * 1_000_000_000 + int((frac or "0").ljust(9, "0"))


def xy(pose) -> list[float]:
    p = pose["position"]
    return [p.get("x", 0.0), p.get("y", 0.0)]


def theta(q: dict) -> float:
    return 2 * math.atan2(q.get("z", 0.0), q.get("w", 0.0))

