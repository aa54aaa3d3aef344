"""Every kind of edit a hostile user makes to a recording ends in "not verified" with the
reason, headless, on the command line and in the window: a command of a robot its own
driver chose (a team's autopilot tick), a checkpoint and an estimates line swapped, a
file downgraded to an older format (lines dropped, the sensor noise edited), a map cell
flipped with its sha256 recomputed. "verified" alone means every line that shapes the run
was checked against the run simulated again."""

from __future__ import annotations

import base64
import json
import zlib
from pathlib import Path

import numpy as np
import pytest

from beacon_sim.cli.main import main
from beacon_sim.core.occupancy import OccupancyGrid
from beacon_sim.core.scenario import load_scenario, load_team_scenario
from beacon_sim.io.recording import RecordingError, load_recording, text_checksum
from beacon_sim.runs.live import Session
from beacon_sim.runs.recorder import Recorder
from beacon_sim.runs.replay import (
    ReplayMismatch,
    ReplaySession,
    recorded_filter_specs,
    recorded_params,
    replay_recording,
)


def objects(path: Path) -> list[dict]:
    return [json.loads(ln) for ln in path.read_text().splitlines() if ln.strip()]


def write(path: Path, objs: list[dict]) -> Path:
    path.write_text("".join(json.dumps(o) + "\n" for o in objs))
    return path


def status_of(path: Path) -> str:
    return replay_recording(load_recording(path)).extra["replay"]["checksum_status"]


def window_status(path: Path) -> str:
    rec = load_recording(path)
    s = ReplaySession(rec, recorded_filter_specs(rec, None)[0], recorded_params(rec, None))
    s.seek(s.total_ticks)
    return s.checksum_status()


@pytest.fixture(scope="module")
def team_file(tmp_path_factory) -> Path:
    """team_sparse on autopilot (its driven robot's driver chooses every command)."""
    team = load_team_scenario("team_sparse")
    path = tmp_path_factory.mktemp("team") / "team.jsonl"
    specs = ["independent", "centralised"]
    s = Session(team, specs, 2, {}, Recorder(path, team, 2, specs))
    s.toggle_autopilot()
    for _ in range(45):
        s.tick()
    s.close()
    return path


@pytest.fixture(scope="module")
def solo_file(tmp_path_factory) -> Path:
    sc = load_scenario("default")
    path = tmp_path_factory.mktemp("solo") / "run.jsonl"
    s = Session(sc, ["ekf"], 4, {}, Recorder(path, sc, 4, ["ekf"], {}))
    s.toggle_autopilot()
    for _ in range(60):
        s.tick()
    s.close()
    return path


def test_the_unedited_files_are_verified(team_file, solo_file):
    assert status_of(team_file) == status_of(solo_file) == "verified"
    assert window_status(team_file) == "verified"


def test_a_command_its_driver_chose_edited_in_a_team_file_is_named(team_file, tmp_path, capsys):
    objs = objects(team_file)
    tick = next(o for o in objs if o["type"] == "tick" and o["k"] == 10)
    assert tick.get("a") is True  # the driven robot's driver chose it: the replay chooses again
    tick["u"][0] += 0.05
    bad = write(tmp_path / "u.jsonl", objs)
    with pytest.raises(ReplayMismatch, match=r"tick 10 .*robot 0's command u \(its driver chose"):
        replay_recording(load_recording(bad))
    assert window_status(bad).startswith("MISMATCH") and "robot 0's command u" in window_status(bad)
    assert main(["replay", str(bad), "--headless"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("beacon-sim: not verified: ") and len(err.strip().splitlines()) == 1


def test_a_checkpoint_and_its_estimates_line_swapped_is_named(solo_file, tmp_path):
    objs = objects(solo_file)
    kinds = [o["type"] for o in objs]
    i = kinds.index("checkpoint")
    assert kinds[i + 1] == "estimates" and objs[i]["k"] == objs[i + 1]["k"]
    objs[i], objs[i + 1] = objs[i + 1], objs[i]
    with pytest.raises(RecordingError, match=r"checkpoint of tick 20 out of order \(after its "
                                             r"estimates line of that tick\): was the file edited"):
        load_recording(write(tmp_path / "swap.jsonl", objs))


def _downgraded(objs: list[dict], version: int) -> list[dict]:
    """As a file of ``version`` would hold it: no maths, no filters or estimates lines, no
    estimate values; version 1, no readings checksums either."""
    out = []
    objs[0]["version"] = version
    for key in ("maths", "maths_description"):
        objs[0].pop(key, None)
    for o in objs:
        if o["type"] in ("filters", "estimates"):
            continue
        for key in ("values", "estimates", "notes") if o["type"] == "end" else ():
            o.pop(key, None)
        if version < 2:
            o.pop("r", None)
            o.pop("readings_checksum", None)
        out.append(o)
    return out


def _edit_noise(header: dict) -> None:
    """The range sensor's noise doubled, and the scenario's checksum recomputed (as the
    format version has it)."""
    text = header["scenario_toml"]
    assert "range_std = 0.05" in text
    header["scenario_toml"] = text.replace("range_std = 0.05", "range_std = 0.1", 1)
    header["scenario_sha256"] = text_checksum(header["scenario_toml"], header["version"])


@pytest.mark.parametrize("version, expected", [
    (1, "not verified: the readings and filter settings (a version 1 file records neither); "
        "the truth verified"),
    (3, "not verified: the filter settings and estimates (not recorded); truth and readings verified"),
])
def test_a_downgraded_file_says_what_it_cannot_check(solo_file, tmp_path, version, expected, capsys):
    path = write(tmp_path / f"v{version}.jsonl", _downgraded(objects(solo_file), version))
    assert status_of(path) == expected
    assert window_status(path) == expected
    assert main(["replay", str(path), "--headless"]) == 0
    assert expected in capsys.readouterr().out


def test_a_downgraded_file_with_its_sensor_noise_edited_is_never_verified(solo_file, tmp_path):
    for version in (1, 2, 3):
        objs = _downgraded(objects(solo_file), version)
        _edit_noise(objs[0])
        status = status_of(write(tmp_path / f"noise{version}.jsonl", objs))
        assert status.startswith("not verified: "), (version, status)
        if version == 1:  # no readings recorded: the one thing it cannot check is named
            assert "the readings" in status
        else:  # the readings differ: a file that does not name its maths cannot tell why
            assert "truth and readings cannot be verified here" in status


def _flip_a_cell(header: dict) -> None:
    """One cell of the stored map flipped, far from anything the run sees, and the map's
    sha256 recomputed as anyone can."""
    m = header["map"]
    cells = bytearray(zlib.decompress(base64.b64decode(m["cells"])))
    cells[0] = 100 if cells[0] != 100 else 0
    m["cells"] = base64.b64encode(zlib.compress(bytes(cells))).decode()
    grid = OccupancyGrid(np.frombuffer(bytes(cells), dtype=np.int8).reshape(m["shape"]).copy(),
                         m["resolution"], tuple(m["origin"]))
    m["sha256"] = grid.sha256()


def test_a_map_cell_flipped_with_its_sha256_recomputed_is_not_verified(tmp_path, capsys):
    sc = load_scenario("office")
    path = tmp_path / "office.jsonl"
    with Recorder(path, sc, 3, [], {}) as rec:
        for k in range(1, 21):
            rec.record_tick(k, None, [])
    assert status_of(path) == "verified"  # the shipped map file, cell for cell
    objs = objects(path)
    _flip_a_cell(objs[0])
    bad = write(tmp_path / "flipped.jsonl", objs)
    status = status_of(bad)
    assert status.startswith("not verified: the stored map (its own sha256 is all it can be "
                             "checked against, and an edit can recompute that; it differs from "
                             "the map file)"), status
    assert window_status(bad).startswith("not verified: the stored map")
    assert main(["replay", str(bad), "--headless"]) == 0
    captured = capsys.readouterr()
    assert "differs from the recorded map" in captured.err and "not verified: the stored map" in captured.out
