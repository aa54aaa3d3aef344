"""Fixtures of the window tests."""

from __future__ import annotations

import pytest
from replay_app_helpers import FILTERS, TICKS

from beacon_sim.core.scenario import load_scenario
from beacon_sim.runs.live import Session
from beacon_sim.runs.recorder import Recorder


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """A live session driven by hand (turns, a click kidnap, a reset), recorded; returns
    the file and the live session's final state."""
    path = tmp_path_factory.mktemp("rec") / "drive.jsonl"
    sc = load_scenario("default")
    live = Session(sc, FILTERS, 3, {}, Recorder(path, sc, 3, FILTERS, {}))
    for k in ("w", "w", "w", "a"):
        live.drive(k)
    for t in range(1, TICKS + 1):
        if t == 60:
            live.drive("d")
        if t == 150:
            live.command({"kind": "kidnap", "pose": [8.0, 5.0, 2.0]})
        if t == 200:
            live.command({"kind": "reset"})
        live.tick()
    state = {"pose": live.true_pose.copy(), "checksum": live.sim.truth_checksum,
             "ekf": live.runner.tracks["ekf"].means[-1].copy()}
    live.close()
    return path, state
