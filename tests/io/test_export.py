"""``beacon-sim export``: a recording (or a headless run) as arrays (.npz) or CSV, with the
filters' estimates, round-tripping exactly."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from recording_helpers import SCENARIO, live_run

from beacon_sim.cli.main import main
from beacon_sim.io.export import csv_paths
from beacon_sim.io.recording import load_recording


@pytest.fixture
def recorded(tmp_path):
    p = tmp_path / "rec_test.toml"
    p.write_text(SCENARIO)
    out = tmp_path / "run.jsonl"
    steps, runner, _, _ = live_run(p, out, ticks=160)
    return out, steps, runner  # runner: the live filters, to compare with the replayed ones


def test_npz_round_trip(recorded, tmp_path):
    rec_path, steps, live = recorded
    out = tmp_path / "trace.npz"
    assert main(["export", str(rec_path), "--out", str(out)]) == 0
    with np.load(out, allow_pickle=False) as z:  # plain arrays, no pickled objects
        a = {k: z[k] for k in z.files}
    recording = load_recording(rec_path)
    assert a["truth"].shape == (161, 3)
    np.testing.assert_array_equal(a["truth"][0], recording.scenario.initial_pose)
    np.testing.assert_array_equal(a["truth"][1:], np.array([s.true_pose for s in steps]))
    np.testing.assert_array_equal(a["control"], [[s.control.v, s.control.omega] for s in steps])
    np.testing.assert_allclose(a["truth_time_s"], np.arange(161) * 0.1)
    # every reading comes back in its row
    for s in steps:
        rows = a["readings_tick"] == s.tick
        want = [r for m in s.measurements for r in m.z]
        ids = [i for m in s.measurements for i in m.beacon_ids]
        assert rows.sum() == len(want)
        if want:
            got = np.column_stack([a["readings_range_m"][rows], a["readings_bearing_rad"][rows]])
            np.testing.assert_array_equal(got, np.array(want))
            assert np.isnan(a["readings_x_m"][rows]).all() and np.isnan(a["readings_theta_rad"][rows]).all()
            np.testing.assert_array_equal(a["readings_beacon_id"][rows], ids)
            assert set(a["readings_kind"][rows]) == {"range_bearing"}
    # events: the scheduled kidnap (12 s) and the two user kidnaps (ticks 40, 130)
    assert sorted(a["events_tick"].tolist()) == [40, 120, 130]
    i = int(np.flatnonzero(a["events_tick"] == 40)[0])
    np.testing.assert_array_equal([a[f"events_{c}_after_{u}"][i] for c, u in (("x", "m"), ("y", "m"),
                                   ("theta", "rad"))], [3.0, 7.0, -2.5])
    assert [json.loads(c)["kind"] for c in a["command_json"]] == ["kidnap", "reset", "kidnap", "toggle"]
    assert json.loads(str(a["header_json"]))["seed"] == 11
    # the recorded filters, replayed: their estimates are the live ones, bit for bit
    assert list(a["filter_names"]) == ["ekf", "dead_reckoning"]
    assert a["est_mean"].shape == (2, 160, 3) and a["est_cov"].shape == (2, 160, 3, 3)
    for i, name in enumerate(a["filter_names"]):
        track = live.tracks[str(name)]
        np.testing.assert_array_equal(a["est_mean"][i], np.array(track.means))
        np.testing.assert_array_equal(a["est_cov"][i], np.array(track.covs))
    assert list(a["filter_failed"]) == ["", ""]


def test_csv_round_trip(recorded, tmp_path):
    rec_path, steps, live = recorded
    out = tmp_path / "trace.csv"
    assert main(["export", str(rec_path), "--out", str(out)]) == 0
    paths = csv_paths(out)
    with paths["truth"].open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 161
    got = np.array([[float(r["x_m"]), float(r["y_m"]), float(r["theta_rad"])] for r in rows[1:]])
    np.testing.assert_array_equal(got, np.array([s.true_pose for s in steps]))  # repr is exact
    assert [float(r["v_mps"]) for r in rows[1:]] == [s.control.v for s in steps]
    with paths["readings"].open() as f:
        meas = list(csv.DictReader(f))
    assert len(meas) == sum(len(m) for s in steps for m in s.measurements)
    first = next(s for s in steps if s.measurements)
    m = first.measurements[0]
    assert int(meas[0]["tick"]) == first.tick and int(meas[0]["beacon_id"]) == int(m.beacon_ids[0])
    assert float(meas[0]["range_m"]) == m.z[0, 0] and float(meas[0]["bearing_rad"]) == m.z[0, 1]
    with paths["events"].open() as f:
        events = list(csv.DictReader(f))
    assert [int(e["tick"]) for e in events] == [40, 120, 130]
    with paths["estimates"].open() as f:
        est = list(csv.DictReader(f))
    assert len(est) == 2 * 160 and {e["filter"] for e in est} == {"ekf", "dead_reckoning"}
    ekf = [e for e in est if e["filter"] == "ekf"]
    track = live.tracks["ekf"]
    np.testing.assert_array_equal([[float(e[k]) for k in ("x_m", "y_m", "theta_rad")] for e in ekf],
                                  np.array(track.means))
    np.testing.assert_array_equal([float(e["cov_xy"]) for e in ekf], np.array(track.covs)[:, 0, 1])


def test_export_of_a_headless_run_equals_run_api(tmp_path, capsys):
    """A scenario instead of a recording: the run ``beacon-sim run`` would make, filters chosen."""
    import beacon_sim as bs

    out = tmp_path / "run.npz"
    assert main(["export", "default", "--filter", "ekf", "--filter", "pf", "--set", "pf.n_particles=200",
                 "--seed", "4", "--duration", "3", "--out", str(out)]) == 0
    r = bs.run("default", ["ekf", "pf"], seed=4, duration=3, params={"pf": {"n_particles": 200}})
    with np.load(out) as z:
        np.testing.assert_array_equal(z["truth"], r.truth)
        np.testing.assert_array_equal(z["est_mean"][1], r.estimates["pf"])
        assert "header_json" not in z.files
    assert main(["export", str(out), "--seed", "1", "--out", str(tmp_path / "x.npz")]) == 2


def test_export_rejects_unknown_suffix(recorded, tmp_path, capsys):
    rec_path, _, _ = recorded
    assert main(["export", str(rec_path), "--out", str(tmp_path / "x.txt")]) == 2
    assert ".npz, .csv or .mcap" in capsys.readouterr().err


def test_export_refuses_a_team_recording_in_one_line(tmp_path, capsys):
    """A team recording is not exported as if it were one robot's: exit 2, one line."""
    team = Path(__file__).parents[1] / "data" / "old_recordings" / "v2_team_sparse.jsonl"
    out = tmp_path / "x.npz"
    assert main(["export", str(team), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "a team recording" in err and "\n" not in err
    assert not out.exists()


def test_exports_name_files_not_the_folders_they_were_in(recorded, tmp_path, capsys):
    """An export is shared, so it names the recorded scenario file and filter
    files by their file names, never by where they were on the machine (the .npz header,
    the .csv tables, the MCAP's messages and metadata)."""
    import shutil

    from mcap.reader import make_reader

    from beacon_sim.io.export import shareable_header

    rec_path, _, _ = recorded
    student = tmp_path / "student_ekf.py"
    shutil.copy(Path(__file__).parents[2] / "examples" / "student_ekf.py", student)
    here = str(tmp_path)
    # the recording names its scenario file by file name (version 4); an export of an older
    # recording, whose header holds a path, is checked with shareable_header below
    assert load_recording(rec_path).header["scenario_source"] == "rec_test.toml"
    for suffix in ("npz", "csv", "mcap"):
        assert main(["export", str(rec_path), "--filter", "ekf", "--filter", f"{student}:StudentEKF",
                     "--out", str(tmp_path / f"x.{suffix}")]) == 0
    capsys.readouterr()
    with np.load(tmp_path / "x.npz", allow_pickle=False) as z:
        words = [w for k in z.files if z[k].dtype.kind == "U" for w in z[k].ravel().tolist()]
        header = json.loads(str(z["header_json"]))
    assert header["scenario_source"] == "rec_test.toml" and header["filters"] == ["ekf", "dead_reckoning"]
    assert words and not [w for w in words if here in w]
    for f in tmp_path.glob("x*.csv"):
        assert here not in f.read_text(), f.name
    with (tmp_path / "x.mcap").open("rb") as f:
        reader = make_reader(f)
        assert not [m.name for m in reader.iter_metadata() if here in json.dumps(m.metadata)]
        assert not [c.topic for _, c, m in reader.iter_messages() if here.encode() in m.data]
    # filter specs of files, as a recording made with them holds them
    got = shareable_header({"scenario_source": "/srv/a/b.toml", "seed": 1,
                            "filters": ["ekf", "/x/y/alice.py:Ekf", "bob=../s/bob.py:Ekf", "pkg.mod:Ekf"]})
    assert got == {"scenario_source": "b.toml", "seed": 1,
                   "filters": ["ekf", "alice.py:Ekf", "bob=bob.py:Ekf", "pkg.mod:Ekf"]}
