"""Live streaming to Foxglove: a WebSocket client on localhost (the Foxglove
protocol, tests/foxglove_client.py) receives a live session, every message decoded with
the schema its channel advertises; and ``beacon-sim play --foxglove PORT`` serves one."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from foxglove_client import FoxgloveClient

from beacon_sim.cli.main import main
from beacon_sim.core.scenario import load_scenario
from beacon_sim.io.foxglove_live import HOST, LiveFoxglove
from beacon_sim.runs.live import Session

ROOT = Path(__file__).resolve().parents[2]


def test_a_client_receives_a_live_session():
    sc = load_scenario("default")
    session = Session(sc, ["ekf", "dead_reckoning"], 3)
    live = LiveFoxglove(sc, session.names, port=0).attach(session)
    try:
        assert live.url == f"ws://{HOST}:{live.port}" and HOST == "127.0.0.1"
        client = FoxgloveClient(live.port)
        client.pump(10, until=lambda c: len(c.subs) >= 13)  # every topic advertised before a tick
        topics = {ch["topic"] for ch in client.channels.values()}
        assert {"/world", "/truth/pose", "/tf", "/trails", "/filters/ekf/stats",
                "/filters/dead_reckoning/scene"} <= topics
        assert client.server_info["name"] == "beacon-sim default"
        truths = {}
        for _ in range(60):
            step = session.tick().steps[0]
            truths[step.tick] = step.true_pose.copy()
            client.pump(0.02)
        client.pump(30, until=lambda c: any(m["tick"] == 60
                                            for _, m in c.messages.get("/filters/ekf/stats", [])))
    finally:
        live.close()
    # a message published before the server took the subscription may be missed: check the
    # ticks that came (in order, the last 30 all there) against the session, number for number
    got = client.messages
    dt_ns = 50_000_000
    ticks = [t // dt_ns for t, _ in got["/truth/pose"] if t > 0]
    assert ticks == sorted(ticks) and set(range(31, 61)) <= set(ticks)
    for t, m in got["/truth/pose"]:
        if t > 0:
            k = t // dt_ns
            assert [m["pose"]["position"]["x"], m["pose"]["position"]["y"]] == list(truths[k][:2])
    ekf = np.array(session.runner.tracks["ekf"].means)  # row k - 1: tick k
    stats = [m for _, m in got["/filters/ekf/stats"]]
    assert {s["tick"] for s in stats} >= set(range(31, 61))
    for s in stats:
        k = s["tick"]
        assert s["err_x_m"] == pytest.approx(ekf[k - 1, 0] - truths[k][0], abs=1e-12)
        assert s["nees"] is not None and s["nees"] >= 0
    assert len(got["/trails"][-1][1]["entities"]) == 3  # truth, ekf, dead_reckoning
    assert got["/world"][-1][1]["entities"][0]["texts"]  # the beacons' labels (sent every second)
    client.close()


def _free_port() -> int:
    with socket.socket() as s:
        s.bind((HOST, 0))
        return s.getsockname()[1]


def test_play_foxglove_serves_the_window_session(tmp_path):
    port = _free_port()
    env = {**os.environ, "PYTHONPATH": str(ROOT), "SDL_VIDEODRIVER": "dummy", "SDL_AUDIODRIVER": "dummy",
           "HOME": str(tmp_path)}
    proc = subprocess.Popen([sys.executable, "-m", "beacon_sim.cli.main", "play", "default", "--no-record",
                             "--autopilot", "--frames", "3000", "--foxglove", str(port)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env,
                            cwd=tmp_path)
    try:
        client = FoxgloveClient(port, timeout=120)
        client.pump(120, until=lambda c: len(c.messages.get("/filters/ekf/pose", [])) >= 10)
        client.close()
    finally:
        proc.terminate()  # our own child, by its handle
        _, err = proc.communicate(timeout=60)
    assert len(client.messages.get("/filters/ekf/pose", [])) >= 10
    assert len(client.messages["/truth/pose"]) >= 10
    assert f"streaming to Foxglove on ws://127.0.0.1:{port}" in err


def test_foxglove_option_errors_are_one_line(tmp_path, capsys):
    assert main(["play", "default", "--foxglove", "70000", "--frames", "1", "--no-record"]) == 2
    assert "--foxglove 70000: expected a port from 0 to 65535" in capsys.readouterr().err
    from recording_helpers import SCENARIO, live_run

    p = tmp_path / "rec_test.toml"
    p.write_text(SCENARIO)
    rec = tmp_path / "run.jsonl"
    live_run(p, rec, ticks=20)
    assert main(["replay", str(rec), "--headless", "--foxglove"]) == 2
    assert "--foxglove streams the replay window: drop --headless" in capsys.readouterr().err


def test_which_clients_connect_by_subprotocol():
    """The SDK's server speaks ``foxglove.sdk.v1``: a client offering it (today's Foxglove app
    offers it beside the older name) connects; one offering only ``foxglove.websocket.v1``
    (older Foxglove Studio releases, Lichtblick) is refused with HTTP 400 (docs/replay.md)."""
    sc = load_scenario("default")
    live = LiveFoxglove(sc, ["ekf"], port=0)
    try:
        for offered in ("foxglove.sdk.v1", "foxglove.websocket.v1, foxglove.sdk.v1"):
            client = FoxgloveClient(live.port, timeout=10, subprotocol=offered)
            client.pump(5, until=lambda c: c.server_info is not None)
            assert client.server_info["name"] == "beacon-sim default"
            client.close()
        with pytest.raises(AssertionError, match="400"):
            FoxgloveClient(live.port, timeout=10, subprotocol="foxglove.websocket.v1")
    finally:
        live.close()
