"""Recording and bit-exact replay of a map session: the walls come back from the
map file the scenario names, the scans replay bit for bit, and mcl's figures are the run's.
The recording names the scenario without a folder: the map file is looked for
beside a shipped scenario, or beside the path an older recording holds."""

from __future__ import annotations

import base64
import json
import shutil
import zlib
from pathlib import Path

import pytest

from beacon_sim.cli.main import main
from beacon_sim.core.occupancy import OCCUPIED, OccupancyGrid, save_map
from beacon_sim.core.scenario import load_scenario
from beacon_sim.io.recording import RecordingError, load_recording
from beacon_sim.runs.headless import run_headless
from beacon_sim.runs.recorder import Recorder


def test_a_recorded_map_session_replays_bit_for_bit(tmp_path, capsys):
    sc = load_scenario("office")
    out = tmp_path / "office.jsonl"
    with Recorder(out, sc, 3, ["mcl", "dead_reckoning"], {}) as rec:
        for k in range(1, 51):
            rec.record_tick(k, None, [])
    assert json.loads(out.read_text().splitlines()[0])["scenario_source"] == "office"
    assert main(["replay", str(out), "--headless", "--json", "--filter", "mcl",
                 "--set", "mcl.max_particles=800", "--set", "mcl.min_particles=200"]) == 0
    captured = capsys.readouterr()
    assert "map" not in captured.err  # the shipped map, found by name, is the recorded one
    got = json.loads(captured.out)
    ref = run_headless(sc, ["mcl"], seed=3, duration=5.0,
                       params={"mcl": {"max_particles": 800, "min_particles": 200}}).as_json()
    assert got["truth_checksum"] == ref["truth_checksum"]
    assert got["replay"]["checksum_status"] == ("not verified: the filter settings and estimates (not "
                                                 "recorded); truth and readings verified")
    assert got["measurements"] == ref["measurements"]
    assert got["measurements"]["laser"] == 25 * 181          # readings counted per beam
    for key in ("pos_rmse_m", "heading_rmse_rad", "anees"):
        assert got["filters"]["mcl"][key] == ref["filters"]["mcl"][key]


def record_office_copy(tmp_path, ticks: int = 40):
    """The office scenario and its map copied under tmp_path (the scenario in scen/, the map
    in assets/maps/ as the TOML's relative path wants), recorded for ``ticks`` ticks."""
    (tmp_path / "scen").mkdir()
    (tmp_path / "assets" / "maps").mkdir(parents=True)
    root = Path(__file__).resolve().parents[2]
    for name in ("office.yaml", "office.pgm"):
        shutil.copy(root / "assets" / "maps" / name, tmp_path / "assets" / "maps" / name)
    toml = tmp_path / "scen" / "office.toml"
    shutil.copy(root / "scenarios" / "office.toml", toml)
    sc = load_scenario(toml)
    out = tmp_path / "office.jsonl"
    with Recorder(out, sc, 5, ["mcl"], {"mcl": {"max_particles": 600, "min_particles": 200}}) as rec:
        for k in range(1, ticks + 1):
            rec.record_tick(k, None, [])
    return sc, out, tmp_path / "assets" / "maps"


def figures(result: dict) -> dict:
    """A filter's figures without its timings and the warning they raise (machine speed)."""
    return {k: v for k, v in result["filters"]["mcl"].items()
            if "per_step" not in k and k != "slow_warning"}


def replay_json(out, capsys) -> tuple[dict, str]:
    assert main(["replay", str(out), "--headless", "--json"]) == 0
    captured = capsys.readouterr()
    return json.loads(captured.out), captured.err


def alter_map(sc, maps: Path) -> None:
    """A wall block painted over the corridor where the robot drives, saved over the map."""
    grid = sc.world.grid
    cells = grid.cells.copy()
    cells[110:130, 100:140] = OCCUPIED
    save_map(OccupancyGrid(cells, grid.resolution, grid.origin), maps / "office.yaml")


def test_the_recording_holds_the_map_and_replays_without_the_file(tmp_path, capsys):
    """The header stores the occupancy grid the run used (with its digest) and names the
    user's scenario by its file name only: with the map files deleted, and again with them
    altered, the replay rebuilds the same world from the recording alone, verified bit for
    bit with the same figures (the user's folder is not recorded, so nothing is looked for
    there)."""
    sc, out, maps = record_office_copy(tmp_path)
    header = json.loads(out.read_text().splitlines()[0])
    assert header["scenario_source"] == "office.toml"
    assert str(tmp_path) not in out.read_text()
    assert header["map"]["file"] == "../assets/maps/office.yaml"
    assert header["map"]["sha256"] == sc.world.grid.sha256()
    assert len(out.read_bytes()) < 50_000       # 96,000 cells, compressed
    ref, err = replay_json(out, capsys)
    assert ref["replay"]["checksum_status"].startswith(
        "not verified: the stored map (its own sha256 is all it can be checked against, and an edit "
        "can recompute that; a user's map file is not looked for);")
    assert ref["replay"]["checksum_status"].endswith("truth and readings verified")
    assert "map" not in err

    for name in ("office.yaml", "office.pgm"):
        (maps / name).unlink()
    gone, err = replay_json(out, capsys)
    assert "map" not in err
    alter_map(sc, maps)
    altered, err = replay_json(out, capsys)
    assert "map" not in err
    for got in (gone, altered):
        assert got["replay"]["checksum_status"] == ref["replay"]["checksum_status"]
        assert got["truth_checksum"] == ref["truth_checksum"]
        assert figures(got) == figures(ref)


def with_header(out: Path, path: Path, edit) -> Path:
    """``out`` rewritten to ``path`` with ``edit(header)`` applied to its header."""
    lines = out.read_text().splitlines(keepends=True)
    header = json.loads(lines[0])
    edit(header)
    path.write_text(json.dumps(header) + "\n" + "".join(lines[1:]))
    return path


def test_an_older_recording_names_a_changed_map_file(tmp_path, capsys):
    """A recording made before format version 4 holds the scenario's path: the map file beside it
    is still looked for, and a missing or altered one is said (the recorded map is used)."""
    sc, out, maps = record_office_copy(tmp_path)

    def as_before(header):
        header["scenario_source"] = str(tmp_path / "scen" / "office.toml")
    old = with_header(out, tmp_path / "old.jsonl", as_before)
    ref, err = replay_json(old, capsys)
    assert "map" not in err                      # the file on disk is the recorded map
    for name in ("office.yaml", "office.pgm"):
        (maps / name).unlink()
    gone, err = replay_json(old, capsys)
    assert "cannot be read" in err and "replaying with the recorded map" in err
    alter_map(sc, maps)
    altered, err = replay_json(old, capsys)
    assert "differs from the recorded map" in err and "replaying with the recorded map" in err
    for got in (gone, altered):
        assert got["truth_checksum"] == ref["truth_checksum"] and figures(got) == figures(ref)


def test_an_edited_stored_map_is_refused(tmp_path):
    _, out, _ = record_office_copy(tmp_path, ticks=5)
    lines = out.read_text().splitlines(keepends=True)
    header = json.loads(lines[0])
    cells = bytearray(zlib.decompress(base64.b64decode(header["map"]["cells"])))
    cells[0] = 100 if cells[0] != 100 else 0
    header["map"]["cells"] = base64.b64encode(zlib.compress(bytes(cells))).decode()
    out.write_text(json.dumps(header) + "\n" + "".join(lines[1:]))
    with pytest.raises(RecordingError, match="stored map was edited"):
        load_recording(out)


def test_a_recording_made_before_the_map_was_stored_still_replays(tmp_path, capsys):
    """A header without "map" (recorded before 0.3.0 stored it, with the scenario's
    path) reads the map file the scenario names, as it did."""
    _, out, _ = record_office_copy(tmp_path, ticks=20)
    ref, _ = replay_json(out, capsys)

    def as_before(header):
        del header["map"]
        header["scenario_source"] = str(tmp_path / "scen" / "office.toml")
    got, _ = replay_json(with_header(out, tmp_path / "old.jsonl", as_before), capsys)
    # the same, but for the stored map, which the old file does not hold (it reads the file)
    gap = "the stored map (its own sha256 is all it can be checked against"
    assert gap in ref["replay"]["checksum_status"] and gap not in got["replay"]["checksum_status"]
    assert got["replay"]["checksum_status"].split("; ")[-1] == \
        ref["replay"]["checksum_status"].split("; ")[-1] == "truth and readings verified"
    assert figures(got) == figures(ref)
