"""Recording and bit-exact replay of a map session (issue 30): the walls come back from the
map file the scenario names, the scans replay bit for bit, and mcl's figures are the run's."""

from __future__ import annotations

import json

from beacon_sim.cli.main import main
from beacon_sim.core.scenario import load_scenario
from beacon_sim.runs.headless import run_headless
from beacon_sim.runs.recorder import Recorder


def test_a_recorded_map_session_replays_bit_for_bit(tmp_path, capsys):
    sc = load_scenario("office")
    out = tmp_path / "office.jsonl"
    with Recorder(out, sc, 3, ["mcl", "dead_reckoning"], {}) as rec:
        for k in range(1, 51):
            rec.record_tick(k, None, [])
    assert main(["replay", str(out), "--headless", "--json", "--filter", "mcl",
                 "--set", "mcl.max_particles=800", "--set", "mcl.min_particles=200"]) == 0
    got = json.loads(capsys.readouterr().out)
    ref = run_headless(sc, ["mcl"], seed=3, duration=5.0,
                       params={"mcl": {"max_particles": 800, "min_particles": 200}}).as_json()
    assert got["truth_checksum"] == ref["truth_checksum"]
    assert got["replay"]["checksum_status"].startswith("verified: truth and readings")
    assert got["measurements"] == ref["measurements"]
    assert got["measurements"]["laser"] == 25 * 181          # readings counted per beam
    for key in ("pos_rmse_m", "heading_rmse_rad", "anees"):
        assert got["filters"]["mcl"][key] == ref["filters"]["mcl"][key]
