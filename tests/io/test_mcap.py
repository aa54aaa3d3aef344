"""MCAP export for Foxglove, written with Foxglove's SDK and read back with the ``mcap``
reader: every message decoded with the schema the file carries (Foxglove's official protobuf
schemas, and JSON Schema for the numeric topics), channels, counts, one timeline, the poses'
numbers exactly, each filter in its own colour, trails, and plottable error / sigma / NEES."""

from __future__ import annotations

import math

import numpy as np
import pytest
from foxglove_client import Decoder
from mcap_helpers import FOXGLOVE, read, stamp_ns, theta, xy
from recording_helpers import SCENARIO, live_run

import beacon_sim as bs
from beacon_sim.cli.main import main


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
    summary, msgs = read(out)  # every message decodes with its schema
    # schemas: Foxglove's official ones (protobuf descriptors), ours for the numbers (JSON Schema)
    ours = {"beacon_sim.FilterStats", "beacon_sim.Readings", "beacon_sim.BoundStats"}
    assert {s.name for s in summary.schemas.values()} == FOXGLOVE | ours
    for s in summary.schemas.values():
        assert s.encoding == ("jsonschema" if s.name in ours else "protobuf")
    names = ("ekf", "dead_reckoning")
    topics = {c.topic: c for c in summary.channels.values()}
    assert set(topics) == {"/world", "/truth/pose", "/tf", "/truth/scene", "/trails", "/readings", "/events",
                           "/readings/values", "/pcrb", "/pcrb/stats",
                           *(f"/filters/{n}/{t}" for n in names for t in ("pose", "scene", "stats"))}
    schema_of = {t: summary.schemas[c.schema_id].name for t, c in topics.items()}
    assert schema_of["/truth/pose"] == schema_of["/filters/ekf/pose"] == "foxglove.PoseInFrame"
    assert {schema_of[t] for t in ("/filters/ekf/scene", "/readings", "/trails")} == {"foxglove.SceneUpdate"}
    assert schema_of["/events"] == "foxglove.Log" and schema_of["/tf"] == "foxglove.FrameTransform"
    # counts: the statistics record and the messages agree with the run
    counts = {summary.channels[cid].topic: n for cid, n in summary.statistics.channel_message_counts.items()}
    reading_ticks = {s.tick for s in steps if any(len(m) for m in s.measurements)}
    expected = {"/world": 1, "/truth/pose": 161, "/tf": 161, "/truth/scene": 161, "/trails": 161,
                "/readings": len(reading_ticks), "/readings/values": len(reading_ticks), "/events": 3,
                "/pcrb": 160, "/pcrb/stats": 160,
                **{f"/filters/{n}/{t}": 160 for n in names for t in ("pose", "scene", "stats")}}
    assert counts == expected
    assert {t: len(v) for t, v in msgs.items()} == expected
    assert sum(expected.values()) == summary.statistics.message_count
    # one timeline: tick k at k * dt (dt = 0.1 s), the message's own stamp equal to its log time
    dt_ns = 100_000_000
    for topic, rows in msgs.items():
        for log_time, _, msg, publish_time in rows:
            assert log_time % dt_ns == 0 and publish_time in (0, log_time)
            stamp = msg["timestamp"] if "timestamp" in msg else msg["entities"][0]["timestamp"]
            assert stamp_ns(stamp) == log_time, topic
    assert [r[0] for r in msgs["/truth/pose"]] == [k * dt_ns for k in range(161)]
    assert [r[0] for r in msgs["/readings"]] == [k * dt_ns for k in sorted(reading_ticks)]
    # the readings as numbers, each range and bearing exactly the step's
    by_tick = {s.tick: s for s in steps}
    for log_time, _, msg, _ in msgs["/readings/values"]:
        s = by_tick[log_time // dt_ns]
        want = [(m.sensor, int(i), float(z[0]), float(z[1])) for m in s.measurements
                for z, i in zip(m.z, m.beacon_ids, strict=True)]
        got = [(r["sensor"], r["beacon_id"], r["range_m"], r["bearing_rad"]) for r in msg["readings"]]
        assert got == want
        assert all(r["kind"] == "range_bearing" and r["x_m"] is None for r in msg["readings"])
    assert [r[0] // dt_ns for r in msgs["/events"]] == [40, 120, 130]
    assert [r[2]["level"] for r in msgs["/events"]] == ["WARNING"] * 3  # kidnaps: warnings
    assert summary.statistics.message_start_time == 0
    assert summary.statistics.message_end_time == 160 * dt_ns
    # numbers: the truth and the filters' poses exactly, the covariance in the metadata
    truth = np.array([s.true_pose for s in steps])
    got = np.array([xy(m["pose"]) for _, _, m, _ in msgs["/truth/pose"][1:]])
    np.testing.assert_array_equal(got, truth[:, :2])
    heading = np.array([theta(m["pose"]["orientation"]) for _, _, m, _ in msgs["/truth/pose"][1:]])
    np.testing.assert_allclose(np.cos(heading - truth[:, 2]), 1.0, atol=1e-12)
    ekf = np.array(live.tracks["ekf"].means)
    got = np.array([xy(m["pose"]) for _, _, m, _ in msgs["/filters/ekf/pose"]])
    np.testing.assert_array_equal(got, ekf[:, :2])
    ent = msgs["/filters/ekf/scene"][-1][2]["entities"][0]
    meta = {kv["key"]: float(kv["value"]) for kv in ent["metadata"]}
    cov = np.array(live.tracks["ekf"].covs[-1])
    assert meta["cov_xy"] == cov[0, 1] and meta["cov_tt"] == cov[2, 2]
    a, b = ent["spheres"][0]["size"]["x"] / 2, ent["spheres"][0]["size"]["y"] / 2
    assert a * b == pytest.approx(-2 * math.log(0.05) * math.sqrt(np.linalg.det(cov[:2, :2])))
    assert xy(ent["arrows"][0]["pose"]) == list(ekf[-1, :2])
    # the beacons, once, at t = 0
    world = msgs["/world"][0][2]["entities"]
    assert [t["text"] for t in world[0]["texts"]] == ["B1", "B2", "B3"]


def _rgb(c: dict) -> tuple:
    return tuple(round(c.get(k, 0.0), 6) for k in "rgb")


def test_colours_trails_and_plottable_numbers(tmp_path):
    r = bs.run("sparse_kidnap", ["ekf", "ukf", "dead_reckoning"], seed=2, duration=30)  # a kidnap at 25 s
    (out,) = r.export(tmp_path / "run.mcap")
    _, msgs = read(out, ["/truth/scene", "/trails", *(f"/filters/{n}/{t}" for n in r.filter_names
                                                       for t in ("scene", "stats"))])
    # each filter's arrow and ellipse in its own colour, the truth's in another
    colours = {"truth": _rgb(msgs["/truth/scene"][5][2]["entities"][0]["arrows"][0]["color"])}
    for name in r.filter_names:
        ent = msgs[f"/filters/{name}/scene"][5][2]["entities"][0]
        colours[name] = _rgb(ent["arrows"][0]["color"])
        assert _rgb(ent["spheres"][0]["color"]) == colours[name]
        assert ent["spheres"][0]["color"]["a"] < 1.0  # the ellipse is see-through
    assert len(set(colours.values())) == 4
    # trails: each tick, the path so far of the truth and of every filter, in their colours
    T = len(r.controls)
    last = {e["id"].split("/trail/")[0]: e for _, _, m, _ in msgs["/trails"] for e in m["entities"]}
    assert set(last) == {"truth", *r.filter_names}
    points: dict[str, list] = {}
    for _, _, m, _ in msgs["/trails"]:
        for e in m["entities"]:
            src, _, piece = e["id"].partition("/trail/")
            points.setdefault(src, {})[int(piece)] = [xy({"position": p}) for p in e["lines"][0]["points"]]
    kidnaps = [int(t) for t, kind in zip(r.events["tick"], r.events["kind"], strict=True) if kind == "kidnap"]
    assert kidnaps  # the truth's path is cut there
    for src, pieces in points.items():
        path, starts = [], []
        for k in sorted(pieces):
            joined = bool(path) and pieces[k][0] == path[-1]  # a piece goes on where the last ended
            starts.append(len(path) if not joined else None)
            path += pieces[k][1:] if joined else pieces[k]
        want = r.truth[:, :2] if src == "truth" else r.estimates[src][:, :2]
        np.testing.assert_array_equal(np.array(path), want)  # the whole path, piece by piece
        assert [s for s in starts if s] == (kidnaps if src == "truth" else [])
        line = last[src]["lines"][0]
        assert _rgb(line["color"]) == colours[src]
    assert len(points["truth"]) > 1  # the path is cut into pieces
    # error, sigma and NEES per filter, the numbers of the estimates table
    table = r.to_frame("estimates")
    for name in r.filter_names:
        stats = [m for _, _, m, _ in msgs[f"/filters/{name}/stats"]]
        assert len(stats) == T
        rows = table[table["filter"] == name]
        for col in ("err_x_m", "err_y_m", "err_theta_rad", "err_pos_m", "nees"):
            np.testing.assert_array_equal([s[col] for s in stats], rows[col].to_numpy())
        np.testing.assert_array_equal([s["sigma_x_m"] for s in stats], np.sqrt(rows["cov_xx"]))
        np.testing.assert_array_equal([s["tick"] for s in stats], rows["tick"])


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
    assert log["level"] == "ERROR" and "Breaks switched off: RuntimeError: on purpose" in log["message"]
    assert msgs["/events"][0][0] == 31 * 50_000_000
    assert len(msgs["/readings"]) == len({int(t) for t in r.readings["tick"]})


def test_the_decoder_refuses_what_the_schemas_refuse():
    """The decoding above is a real check: a message its schema refuses raises."""
    import json

    import jsonschema
    from google.protobuf.message import DecodeError

    from beacon_sim.io.foxglove import STATS_SCHEMA, foxglove_modules

    dec = Decoder()
    with pytest.raises(jsonschema.ValidationError):
        dec.decode("beacon_sim.FilterStats", "jsonschema", json.dumps(STATS_SCHEMA).encode(), b'{"tick": 1}')
    _, _, m = foxglove_modules()
    schema = m.PoseInFrame.get_schema()
    good = m.PoseInFrame(frame_id="world").encode()
    assert dec.decode(schema.name, schema.encoding, schema.data, good)["frame_id"] == "world"
    with pytest.raises(DecodeError):
        dec.decode(schema.name, schema.encoding, schema.data, b"\xff\xff\xff")
