"""MCAP export of a map session: each scan as a foxglove.LaserScan (the step's
ranges, the beam angles, the true pose as its origin) and the occupancy grid once as a
foxglove.Grid (size, resolution, origin and cells of the map), through the SDK the beacon
world uses; read back with the ``mcap`` reader and decoded with the schemas in the file,
and received live by a WebSocket client."""

from __future__ import annotations

import base64
import math

import numpy as np
from mcap_helpers import read, stamp_ns, theta, xy

from beacon_sim.cli.main import main
from beacon_sim.core.raycast import beam_angles
from beacon_sim.core.scenario import load_scenario
from beacon_sim.runs.headless import run_headless
from beacon_sim.runs.recorder import Recorder


def grid_matches(msg: dict, grid) -> None:
    rows, cols = grid.cells.shape
    assert msg["frame_id"] == "world"
    assert msg["column_count"] == cols
    assert msg["cell_size"] == {"x": grid.resolution, "y": grid.resolution}
    assert msg["row_stride"] == cols and msg["cell_stride"] == 1
    assert msg["fields"] == [{"name": "occupancy", "type": "INT8"}]   # offset 0 is proto3's default
    assert xy(msg["pose"]) == [grid.origin[0], grid.origin[1]]
    assert math.isclose(theta(msg["pose"]["orientation"]), grid.origin[2], abs_tol=1e-12)
    cells = np.frombuffer(base64.b64decode(msg["data"]), dtype=np.int8).reshape(-1, cols)
    assert cells.shape == (rows, cols)
    np.testing.assert_array_equal(cells, grid.cells)   # row 0 = the bottom row, as the map's


def test_a_corridor_run_exports_its_scans_and_map(tmp_path):
    out = tmp_path / "corridor.mcap"
    assert main(["export", "corridor", "--filter", "dead_reckoning", "--duration", "2",
                 "--out", str(out)]) == 0
    sc = load_scenario("corridor")
    ref = run_headless(sc, ["dead_reckoning"], duration=2.0)
    summary, msgs = read(out)
    topics = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
    assert topics["/map"] == "foxglove.Grid"
    assert topics["/scan/laser"] == "foxglove.LaserScan"
    (map_msg,) = msgs["/map"]                         # once, at the start
    assert map_msg[0] == 0
    assert sc.world.grid.origin[1] == -1.0            # the corridor's grid starts at y = -1
    grid_matches(map_msg[2], sc.world.grid)

    dt_ns = round(sc.dt * 1e9)
    scans = {log_time: m for log_time, _, m, _ in msgs["/scan/laser"]}
    expected = [(s.tick, s.true_pose, m.z) for s in ref.steps for m in s.measurements
                if m.sensor == "laser"]
    assert len(expected) == 10 and len(scans) == len(expected)   # 2 s at 5 Hz
    rel = beam_angles(120, 2 * math.pi)
    for tick, pose, z in expected:
        msg = scans[tick * dt_ns]
        assert stamp_ns(msg["timestamp"]) == tick * dt_ns
        assert msg["frame_id"] == "world"
        np.testing.assert_array_equal(msg["ranges"], z[:, 0])        # the step's scan, exactly
        assert 0 < min(msg["ranges"]) and max(msg["ranges"]) <= 4.0
        assert xy(msg["pose"]) == [pose[0], pose[1]]
        assert math.isclose(theta(msg["pose"]["orientation"]), pose[2], abs_tol=1e-12)
        assert msg["start_angle"] == rel[0]
        assert math.isclose(msg["end_angle"], rel[0] + 2 * math.pi * 119 / 120, rel_tol=1e-12)
    # the scans are not drawn as fixes among the beacon readings
    assert "/readings" not in msgs


def test_a_recorded_office_session_exports_its_scans_and_map(tmp_path):
    sc = load_scenario("office")
    rec = tmp_path / "office.jsonl"
    with Recorder(rec, sc, 3, ["dead_reckoning"], {}) as r:
        for k in range(1, 11):
            r.record_tick(k, None, [])
    out = tmp_path / "office.mcap"
    assert main(["export", str(rec), "--out", str(out)]) == 0
    ref = run_headless(sc, ["dead_reckoning"], seed=3, duration=1.0)
    _, msgs = read(out, topics=["/map", "/scan/laser"])
    (map_msg,) = msgs["/map"]
    grid_matches(map_msg[2], sc.world.grid)
    scans = msgs["/scan/laser"]
    expected = [m.z for s in ref.steps for m in s.measurements if m.sensor == "laser"]
    assert len(scans) == len(expected) > 0
    fov = 4.712389
    for (_, _, msg, _), z in zip(scans, expected, strict=True):
        assert len(msg["ranges"]) == 181
        np.testing.assert_array_equal(msg["ranges"], z[:, 0])
        assert math.isclose(msg["start_angle"], -fov / 2, rel_tol=1e-12)
        assert math.isclose(msg["end_angle"], fov / 2, rel_tol=1e-12)


def test_an_npz_export_keeps_each_beam_range_and_angle(tmp_path):
    out = tmp_path / "corridor.npz"
    assert main(["export", "corridor", "--filter", "dead_reckoning", "--duration", "1",
                 "--out", str(out)]) == 0
    ref = run_headless(load_scenario("corridor"), ["dead_reckoning"], duration=1.0)
    z = np.vstack([m.z for s in ref.steps for m in s.measurements if m.sensor == "laser"])
    with np.load(out) as a:
        rows = a["readings_kind"] == "range_finder"
        np.testing.assert_array_equal(a["readings_range_m"][rows], z[:, 0])
        np.testing.assert_array_equal(a["readings_bearing_rad"][rows], z[:, 1])


def test_the_live_server_streams_the_scans_and_the_map():
    from foxglove_client import FoxgloveClient

    from beacon_sim.io.foxglove_live import LiveFoxglove
    from beacon_sim.runs.live import Session

    sc = load_scenario("corridor")
    session = Session(sc, ["dead_reckoning"], 4)
    live = LiveFoxglove(sc, session.names, port=0).attach(session)
    try:
        client = FoxgloveClient(live.port)
        wanted = {"/map", "/scan/laser"}
        client.pump(10, until=lambda c: wanted <= {ch["topic"] for ch in c.channels.values()})
        scans = {}
        for _ in range(40):
            step = session.tick().steps[0]
            for m in step.measurements:
                if m.sensor == "laser":
                    scans[step.tick] = m.z[:, 0].copy()
            client.pump(0.02)
        dt_ns = round(sc.dt * 1e9)
        client.pump(30, until=lambda c: any(t == 40 * dt_ns for t, _ in c.messages.get("/scan/laser", [])))
    finally:
        live.close()
    got = client.messages
    assert got["/map"], "the map is sent with /world"
    grid_matches(got["/map"][-1][1], sc.world.grid)
    assert set(range(22, 41, 2)) <= {t // dt_ns for t, _ in got["/scan/laser"]}
    for t, msg in got["/scan/laser"]:
        np.testing.assert_array_equal(msg["ranges"], scans[t // dt_ns])
    client.close()
