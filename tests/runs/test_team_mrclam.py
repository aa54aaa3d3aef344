"""MRCLAM robot sightings kept for the team run (barcodes mapped through each
folder's own Barcodes.dat), and `beacon-sim mrclam DIR --team` on Dataset 6 when present."""

from __future__ import annotations

import json

import numpy as np
import pytest
from mrclam_helpers import make_folder

from beacon_sim.cli.main import main
from beacon_sim.core.team_models import relative_range_bearing
from beacon_sim.io.mrclam import load_mrclam


def test_robot_sightings_are_kept_on_request_and_mapped_per_folder(tmp_path):
    f = tmp_path / "Set"
    info = make_folder(f, seconds=20.0)
    plain = load_mrclam(f, 1)
    team = load_mrclam(f, 1, robot_sightings=True)
    assert len(plain.sightings) == 0
    np.testing.assert_array_equal(team.measurements, plain.measurements)  # landmarks unchanged
    assert team.dropped == plain.dropped
    assert len(team.sightings) == info["n_robot"] > 0
    assert set(team.sightings[:, 1].astype(int)) == {2}  # barcode 14 is subject 2 in this folder
    # another folder whose Barcodes.dat gives barcode 14 to subject 3 (and 41 to 2)
    text = (f / "Barcodes.dat").read_text()
    text = text.replace("  2 \t  14", "  2 \t  41").replace("  3 \t  41", "  3 \t  14")
    (f / "Barcodes.dat").write_text(text)
    assert set(load_mrclam(f, 1, robot_sightings=True).sightings[:, 1].astype(int)) == {3}


def test_dataset6_sightings_match_the_ground_truth_of_both_robots(mrclam_dataset6):
    data = {r: load_mrclam(mrclam_dataset6, r, robot_sightings=True) for r in range(1, 6)}
    for r, d in data.items():
        s = d.sightings
        assert len(s) == d.dropped["robot_sightings"] > 300
        assert r not in set(s[:, 1].astype(int)) and set(s[:, 1].astype(int)) <= {1, 2, 3, 4, 5}
        me, ok_me = d.truth_at(s[:, 0])
        errs = []
        for j in range(1, 6):
            rows = s[:, 1] == j
            if not rows.any():
                continue
            them, ok = data[j].truth_at(s[rows, 0])
            good = ok & ok_me[rows]
            errs += [relative_range_bearing(a, b)[0] - z for a, b, z in
                     zip(me[rows][good], them[good], s[rows, 2][good], strict=True)]
        assert np.median(np.abs(errs)) < 0.1, (r, np.median(np.abs(errs)))  # right subjects


@pytest.mark.slow  # a Dataset 6 run of all five robots, about 11 s of CPU
def test_cli_mrclam_team_runs_all_five_robots(capsys, mrclam_dataset6):
    assert main(["mrclam", str(mrclam_dataset6), "--team", "--duration", "60", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["robots"] == [1, 2, 3, 4, 5] and d["dataset"] == mrclam_dataset6.name  # not its path
    assert set(d["filters"]) == {"independent", "centralised", "decentralised", "ci"}
    assert d["failed"] == {}
    for name in d["filters"]:
        for r in "12345":
            assert d["filters"][name][r]["pos_rmse_m"] < 1.0
    assert main(["mrclam", str(mrclam_dataset6), "--team", "--robot", "1"]) == 2
    assert main(["mrclam", str(mrclam_dataset6)]) == 2
