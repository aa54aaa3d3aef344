"""MCAP export for Foxglove, read back with the ``mcap`` reader: channels, schemas, message
counts, time stamps on one timeline, and the poses' numbers exactly."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from mcap.reader import make_reader
from test_recording import SCENARIO, live_run

import beacon_sim as bs
from beacon_sim.cli.main import main

FOXGLOVE = {"foxglove.PoseInFrame", "foxglove.FrameTransform", "foxglove.SceneUpdate", "foxglove.Log"}


def read(path):
    """(summary, {topic: [(log_time, schema name, message dict)]})."""
    with path.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        by_topic: dict[str, list] = {}
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            by_topic.setdefault(channel.topic, []).append(
                (message.log_time, schema.name, json.loads(message.data), message.publish_time))
    return summary, by_topic


def theta(q: dict) -> float:
    return 2 * math.atan2(q["z"], q["w"])


@pytest.fixture
def recorded(tmp_path):
    p = tmp_path / "rec_test.toml"
    p.write_text(SCENARIO)
    out = tmp_path / "run.jsonl"
    steps, runner, _, _ = live_run(p, out, ticks=160)
    return out, steps, runner


def test_recording_round_trip(recorded, tmp_path):
    rec_path, steps, live = recorded
    out = tmp_path / "run.mcap"
    assert main(["export", str(rec_path), "--out", str(out)]) == 0
    summary, msgs = read(out)
    # schemas: Foxglove's well-known names, JSON Schema documents
    assert {s.name for s in summary.schemas.values()} == FOXGLOVE
    for s in summary.schemas.values():
        assert s.encoding == "jsonschema" and json.loads(s.data)["type"] == "object"
    topics = {c.topic: c for c in summary.channels.values()}
    assert set(topics) == {"/world", "/truth/pose", "/tf", "/readings", "/events",
                           "/filters/ekf/pose", "/filters/ekf/covariance",
                           "/filters/dead_reckoning/pose", "/filters/dead_reckoning/covariance"}
    assert all(c.message_encoding == "json" for c in topics.values())
    schema_of = {t: summary.schemas[c.schema_id].name for t, c in topics.items()}
    assert schema_of["/truth/pose"] == schema_of["/filters/ekf/pose"] == "foxglove.PoseInFrame"
    assert schema_of["/filters/ekf/covariance"] == schema_of["/readings"] == "foxglove.SceneUpdate"
    assert schema_of["/events"] == "foxglove.Log" and schema_of["/tf"] == "foxglove.FrameTransform"
    # counts: the statistics record and the messages agree with the run
    counts = {summary.channels[cid].topic: n for cid, n in summary.statistics.channel_message_counts.items()}
    reading_ticks = {s.tick for s in steps if any(len(m) for m in s.measurements)}
    expected = {"/world": 1, "/truth/pose": 161, "/tf": 161, "/readings": len(reading_ticks),
                "/events": 3, "/filters/ekf/pose": 160, "/filters/ekf/covariance": 160,
                "/filters/dead_reckoning/pose": 160, "/filters/dead_reckoning/covariance": 160}
    assert counts == expected
    assert {t: len(v) for t, v in msgs.items()} == expected
    # one timeline: tick k at k * dt (dt = 0.1 s), the message's own stamp equal to its log time
    dt_ns = 100_000_000
    for topic, rows in msgs.items():
        for log_time, _, msg, publish_time in rows:
            assert publish_time == log_time and log_time % dt_ns == 0
            stamp = msg["timestamp"] if "timestamp" in msg else msg["entities"][0]["timestamp"]
            assert stamp["sec"] * 1_000_000_000 + stamp["nsec"] == log_time, topic
    assert [r[0] for r in msgs["/truth/pose"]] == [k * dt_ns for k in range(161)]
    assert [r[0] for r in msgs["/readings"]] == [k * dt_ns for k in sorted(reading_ticks)]
    assert [r[0] // dt_ns for r in msgs["/events"]] == [40, 120, 130]
    assert [r[2]["level"] for r in msgs["/events"]] == [3, 3, 3]  # kidnaps: warnings
    assert summary.statistics.message_start_time == 0
    assert summary.statistics.message_end_time == 160 * dt_ns
    # numbers: the truth and the filters' poses exactly, the covariance in the metadata
    truth = np.array([s.true_pose for s in steps])
    got = np.array([[m["pose"]["position"]["x"], m["pose"]["position"]["y"]] for _, _, m, _ in
                    msgs["/truth/pose"][1:]])
    np.testing.assert_array_equal(got, truth[:, :2])
    heading = np.array([theta(m["pose"]["orientation"]) for _, _, m, _ in msgs["/truth/pose"][1:]])
    np.testing.assert_allclose(np.cos(heading - truth[:, 2]), 1.0, atol=1e-12)
    ekf = np.array(live.tracks["ekf"].means)
    got = np.array([[m["pose"]["position"]["x"], m["pose"]["position"]["y"]] for _, _, m, _ in
                    msgs["/filters/ekf/pose"]])
    np.testing.assert_array_equal(got, ekf[:, :2])
    ent = msgs["/filters/ekf/covariance"][-1][2]["entities"][0]
    meta = {kv["key"]: float(kv["value"]) for kv in ent["metadata"]}
    cov = np.array(live.tracks["ekf"].covs[-1])
    assert meta["cov_xy"] == cov[0, 1] and meta["cov_tt"] == cov[2, 2]
    a, b = ent["spheres"][0]["size"]["x"] / 2, ent["spheres"][0]["size"]["y"] / 2
    assert a * b == pytest.approx(-2 * math.log(0.05) * math.sqrt(np.linalg.det(cov[:2, :2])))
    # the beacons, once, at t = 0
    world = msgs["/world"][0][2]["entities"]
    assert [t["text"] for t in world[0]["texts"]] == ["B1", "B2", "B3"]


def test_headless_run_from_the_api_logs_a_failed_filter(tmp_path):
    class Breaks(bs.FilterBase):
        """Dead still, then raises on its 31st predict."""

        def reset(self, initial):
            self.mean, self.cov, self.n = initial.mean.copy(), initial.cov.copy(), 0

        def predict(self, control, dt):
            self.n += 1
            if self.n > 30:
                raise RuntimeError("on purpose")

        def update(self, measurements):
            pass

        def estimate(self):
            return self.mean.copy(), self.cov.copy()

    r = bs.run("default", ["ekf", Breaks], seed=1, duration=5)
    (out,) = r.export(tmp_path / "run.mcap")
    _, msgs = read(out)
    assert len(msgs["/truth/pose"]) == 101 and len(msgs["/filters/Breaks/pose"]) == 30
    (log,) = [m for _, _, m, _ in msgs["/events"]]
    assert log["level"] == 4 and "Breaks switched off: RuntimeError: on purpose" in log["message"]
    assert msgs["/events"][0][0] == 31 * 50_000_000
    assert len(msgs["/readings"]) == len({int(t) for t in r.readings["tick"]})
