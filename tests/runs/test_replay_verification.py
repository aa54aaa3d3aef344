"""What "verified" means: a version 3 recording stores the effective filter
parameters and digests of the estimates, so replay checks everything that shapes a result
and names the field an edit touched; older files say what they cover; an optional HMAC
signs the file; two sessions never write one file; the window shows a mismatch."""

from __future__ import annotations

import dataclasses
import datetime
import hashlib
import json
import os
import re
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pygame
import pytest

from beacon_sim.app import palette
from beacon_sim.app.replay import ReplayApp
from beacon_sim.cli.main import main
from beacon_sim.core.scenario import load_scenario, load_team_scenario
from beacon_sim.io.recording import (
    FORMAT_VERSION,
    KEY_VARIABLE,
    RecordingError,
    default_recording_path,
    load_recording,
)
from beacon_sim.runs.live import Session
from beacon_sim.runs.recorder import Recorder
from beacon_sim.runs.replay import (
    ReplayMismatch,
    ReplaySession,
    recorded_filter_specs,
    recorded_params,
    replay_recording,
)

OLD = Path(__file__).parents[1] / "data" / "old_recordings"
FILTERS = ["ekf", "dead_reckoning"]


def record(path: Path, ticks: int = 60, scenario: str = "default", filters=FILTERS,
           params=None, seed: int = 4) -> Session:
    """A live session on autopilot with a kidnap and a reset, recorded to ``path``."""
    sc = load_scenario(scenario)
    params = params or {}
    s = Session(sc, list(filters), seed, params, Recorder(path, sc, seed, list(filters), params))
    s.toggle_autopilot()
    for k in range(1, ticks + 1):
        if k == 15:
            s.command({"kind": "kidnap", "pose": [3.0, 2.0, 0.5]})
        if k == 35:
            s.command({"kind": "reset"})
        s.tick()
    s.close()
    return s


def objects(path: Path) -> list[dict]:
    return [json.loads(ln) for ln in path.read_text().splitlines() if ln.strip()]


def write(path: Path, objs: list[dict]) -> Path:
    path.write_text("".join(json.dumps(o) + "\n" for o in objs))
    return path


@pytest.fixture(scope="module")
def recorded(tmp_path_factory) -> tuple[Path, Session]:
    path = tmp_path_factory.mktemp("v3") / "run.jsonl"
    return path, record(path)


def test_a_session_records_version_4_and_replays_verified(recorded):
    path, live = recorded
    objs = objects(path)
    assert objs[0]["version"] == FORMAT_VERSION == 4 and len(objs[0]["scenario_sha256"]) == 64
    assert objs[1]["type"] == "filters" and set(objs[1]["filters"]) == set(FILTERS)
    assert any(o["type"] == "estimates" for o in objs) and "estimates" in objs[-1]
    res = replay_recording(load_recording(path))
    assert res.extra["replay"]["checksum_status"] == "verified"
    np.testing.assert_array_equal(res.runner.tracks["ekf"].means[-1],
                                  live.runner.tracks["ekf"].means[-1])


def test_the_effective_parameters_come_from_the_built_filter(tmp_path):
    """Defaults included, and the stored scenario's [filters.NAME] merged in (not a table of
    defaults): what the filter really ran with."""
    text = load_scenario("default").source
    scenario = tmp_path / "s.toml"
    scenario.write_text(Path(text).read_text() + "\n[filters.ekf]\ngate_chi2 = 7.5\n")
    sc = load_scenario(scenario)
    path = tmp_path / "r.jsonl"
    s = Session(sc, ["ekf"], 1, {}, Recorder(path, sc, 1, ["ekf"], {}))
    s.tick()
    s.close()
    settings = objects(path)[1]["filters"]["ekf"]["params"]
    assert settings == s.runner.tracks["ekf"].filter.params and settings["gate_chi2"] == 7.5
    assert objects(path)[0]["params"] == {}  # the header holds the --set overrides only


@pytest.mark.parametrize("edit, field", [
    ("header-params", "ekf.gate_chi2 recorded as 0.0, but 3.0 now"),
    ("header-filters", "the header's filters list differs from the filters line"),
    ("scenario-filters", "ekf.gate_chi2 recorded as 0.0, but 2.0 now"),
    ("params-and-filters-line", "the estimates of filter ekf"),
    ("digest", "the estimates of filter dead_reckoning"),
    ("end-digest", "the estimates of filter ekf (their digest after tick 60) at the end"),
    ("estimates-extra-filter", "filter 'pf' of the estimates line is not among"),
])  # (an edit of the checkpoint or estimates lines' order: test_a_moved_checkpoint_is_an_edit)
def test_an_edited_recording_is_never_verified_and_the_field_is_named(recorded, tmp_path, edit, field):
    path, _ = recorded
    objs = objects(path)
    h = objs[0]
    if edit == "header-params":
        h["params"] = {"ekf": {"gate_chi2": 3.0}}
    elif edit == "header-filters":
        h["filters"] = ["ekf"]
    elif edit == "scenario-filters":  # and the checksum recomputed, as anyone can
        h["scenario_toml"] += "\n[filters.ekf]\ngate_chi2 = 2.0\n"
        h["scenario_sha256"] = hashlib.sha256(h["scenario_toml"].encode()).hexdigest()
    elif edit == "params-and-filters-line":  # consistent everywhere but in the digests
        h["params"] = {"ekf": {"gate_chi2": 3.0}}
        objs[1]["filters"]["ekf"]["params"]["gate_chi2"] = 3.0
    elif edit == "digest":
        line = next(o for o in objs if o["type"] == "estimates")
        line["digests"]["dead_reckoning"] = "0" * 64
    elif edit == "end-digest":
        objs[-1]["estimates"]["ekf"] = "f" * 64
    elif edit == "estimates-extra-filter":
        next(o for o in objs if o["type"] == "estimates")["digests"]["pf"] = "0" * 64
    bad = write(tmp_path / f"{edit}.jsonl", objs)
    with pytest.raises(ReplayMismatch, match="edited") as info:
        replay_recording(load_recording(bad))
    assert field in str(info.value)
    rec = load_recording(bad)  # the window's check says the same (built as the CLI builds it)
    s = ReplaySession(rec, recorded_filter_specs(rec, None)[0], recorded_params(rec, None))
    s.seek(s.total_ticks)
    assert s.checksum_status().startswith("MISMATCH") and field.split(" (")[0] in s.mismatch


@pytest.mark.parametrize("edit", ["drop-checkpoint", "drop-estimates", "move-checkpoint"])
def test_a_moved_or_removed_checkpoint_is_an_edit(recorded, tmp_path, edit):
    objs = objects(recorded[0])
    i = next(i for i, o in enumerate(objs) if o["type"] == ("estimates" if "estimates" in edit
                                                             else "checkpoint"))
    if edit.startswith("drop"):
        del objs[i]
    else:
        objs[i]["k"] -= 1
    with pytest.raises(RecordingError, match=r"was the file edited|after the line of tick"):
        load_recording(write(tmp_path / "e.jsonl", objs))


def test_a_16_digit_scenario_checksum_in_version_3_is_an_edit(recorded, tmp_path):
    objs = objects(recorded[0])
    objs[0]["scenario_sha256"] = objs[0]["scenario_sha256"][:16]
    with pytest.raises(RecordingError, match="stored scenario was edited"):
        load_recording(write(tmp_path / "short.jsonl", objs))


def test_other_filters_or_set_are_verified_for_truth_and_readings_only(recorded, capsys):
    path, _ = recorded
    rec = load_recording(path)
    assert replay_recording(rec, ["ukf"]).extra["replay"]["checksum_status"] == (
        "not verified: the estimates (other filters or parameters than the recorded ones); "
        "truth and readings verified")
    status = replay_recording(rec, None, {"ekf": {"gate_chi2": 3.0}}).extra["replay"]["checksum_status"]
    assert status.startswith("not verified: the estimates (other filters")
    # the recorded filters named explicitly, in order: everything is compared
    assert replay_recording(rec, list(FILTERS)).extra["replay"]["checksum_status"] == "verified"


def test_filters_switched_off_or_reloaded_live_are_listed_not_compared(tmp_path):
    """A filter the window switched off (e.g. over its time limit) or reloaded live cannot
    be compared after that: the status lists it instead of claiming it, or of a mismatch."""
    sc = load_scenario("default")
    path = tmp_path / "r.jsonl"
    s = Session(sc, FILTERS, 1, {}, Recorder(path, sc, 1, FILTERS, {}))
    s.toggle_autopilot()
    for k in range(1, 61):
        if k == 25:  # a hot reload installs a new track
            s.runner.tracks["ekf"] = dataclasses.replace(s.runner.tracks["ekf"])
        if k == 40:
            s.runner.fail("dead_reckoning", "time limit: a step took over 0.5 s", "", s.sim.time)
        s.tick()
    s.close()
    status = status_of(path)
    assert re.fullmatch(r"not verified: dead_reckoning: switched off live at tick \d+: time limit: "
                        r"a step took over 0.5 s; ekf: reloaded live at tick \d+: its estimates are "
                        r"not compared; truth, readings, filter settings and the other estimates "
                        r"verified", status), status


def test_a_file_without_filter_settings_says_so(tmp_path):
    sc = load_scenario("default")
    path = tmp_path / "bare.jsonl"
    with Recorder(path, sc, 2, ["ekf"]) as rec:  # no runner attached
        for k in range(1, 21):
            rec.record_tick(k, None)
    status = replay_recording(load_recording(path)).extra["replay"]["checksum_status"]
    assert status == ("not verified: the filter settings and estimates (not recorded); "
        "truth and readings verified")


def not_verified(tick: int, dt: float) -> str:
    """The status of a file that does not name its maths whose readings differ here."""
    return (f"not verified: made before beacon-sim's portable maths (or on a machine whose maths "
            f"differs), so its truth and readings cannot be verified here (the replay first "
            f"differs at tick {tick}, t = {tick * dt:g} s, checked against its readings "
            f"checksum); replayed from its recorded commands")


#: What each old file replays with since the portable maths: the truth of the
#: sparse_kidnap run did not move (the portable sin and cos equal the C library's on its
#: poses), its bearings did.
OLD_STATUS = {
    "v1_sparse_kidnap.jsonl": "not verified: the readings and filter settings (a version 1 file "
                              "records neither); the truth verified",
    "v2_sparse_kidnap.jsonl": not_verified(2, 0.1),
    "v2_team_sparse.jsonl": not_verified(2, 0.05),
    "v3_sparse_kidnap.jsonl": not_verified(4, 0.1),
    "v3_team_sparse.jsonl": not_verified(2, 0.05),
}


def test_every_old_recording_replays_with_a_true_status(capsys):
    """The files under tests/data/old_recordings were written by versions 1 to 3, before
    beacon-sim's portable maths and before a recording named the maths that made it: each
    replays to its end (exit 0) from its recorded commands, with a status that says what it
    covers; where its readings differ here, that they cannot be verified: never "edited",
    never "verified"."""
    files = sorted(OLD.glob("*.jsonl"))
    assert {f.name for f in files} == set(OLD_STATUS)
    for f in files:
        rec = load_recording(f)
        assert rec.complete and rec.version in (1, 2, 3) and rec.maths is None
        out = replay_recording(rec)
        assert len(out.steps) == len(rec.ticks), f.name
        assert out.extra["replay"]["checksum_status"] == OLD_STATUS[f.name], f.name
        assert main(["replay", str(f), "--headless"]) == 0
        assert OLD_STATUS[f.name] in capsys.readouterr().out
        s = ReplaySession(rec, recorded_filter_specs(rec, None)[0], recorded_params(rec, None))
        s.seek(s.total_ticks)  # the window says the same, with no mismatch (exit 0)
        assert s.mismatch is None and s.checksum_status() == OLD_STATUS[f.name], f.name


# ------------------------------------------------------------------------------ signing
@pytest.fixture(scope="module")
def signed(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("signed") / "signed.jsonl"
    mp = pytest.MonkeyPatch()
    mp.setenv(KEY_VARIABLE, "teacher's key")
    try:
        record(path, ticks=50)
    finally:
        mp.undo()
    return path


def status_of(path: Path) -> str:
    return replay_recording(load_recording(path)).extra["replay"]["checksum_status"]


def test_a_signed_recording_is_signed_and_verified_with_the_key(signed, monkeypatch):
    objs = objects(signed)
    assert objs[0]["signed"] is True and objs[-1]["type"] == "signature"
    assert sum(o["type"] == "signature" for o in objs) == 1 + 50 // 20  # every checkpoint, the end
    monkeypatch.setenv(KEY_VARIABLE, "teacher's key")
    assert status_of(signed) == "signed and verified"
    monkeypatch.delenv(KEY_VARIABLE)
    assert status_of(signed) == f"verified; signed (not checked: {KEY_VARIABLE} is not set)"


def test_another_key_or_a_recomputed_edit_does_not_match(signed, tmp_path, monkeypatch):
    monkeypatch.setenv(KEY_VARIABLE, "a student's guess")
    with pytest.raises(ReplayMismatch, match="signature does not match"):
        status_of(signed)
    # an edit with every checksum and digest consistent still breaks the signature: here the
    # seed in the header with nothing else (the truth would differ), and a checkpoint's
    # time, which no checksum covers
    monkeypatch.setenv(KEY_VARIABLE, "teacher's key")
    objs = objects(signed)
    next(o for o in objs if o["type"] == "checkpoint")["time"] += 1e-9
    with pytest.raises(ReplayMismatch, match="signature does not match"):
        status_of(write(tmp_path / "edited.jsonl", objs))
    assert main(["replay", str(tmp_path / "edited.jsonl"), "--headless"]) == 2


def test_an_unsigned_file_says_not_signed_when_a_key_is_given(recorded, monkeypatch):
    monkeypatch.setenv(KEY_VARIABLE, "teacher's key")
    assert status_of(recorded[0]) == "verified; not signed"


def test_a_signed_file_cut_short_is_signed_up_to_its_last_signature(signed, tmp_path, monkeypatch):
    monkeypatch.setenv(KEY_VARIABLE, "teacher's key")
    lines = signed.read_text().splitlines()
    cut = tmp_path / "cut.jsonl"
    cut.write_text("\n".join(lines[:-4]) + "\n")
    status = status_of(cut)
    assert status.startswith("verified up to the last complete tick; signed and verified up to line")
    assert "(the lines after it are not signed)" in status


# ------------------------------------------------------------------------------ team
def test_a_team_recording_stores_settings_and_an_edit_is_named(tmp_path):
    team = load_team_scenario("team_sparse")
    path = tmp_path / "team.jsonl"
    specs = ["independent", "centralised"]
    s = Session(team, specs, 2, {}, Recorder(path, team, 2, specs))
    for _ in range(45):
        s.tick()
    s.close()
    objs = objects(path)
    assert objs[1]["type"] == "filters" and set(objs[1]["filters"]) == set(specs)
    assert replay_recording(load_recording(path)).extra["replay"]["checksum_status"] == "verified"
    objs[0]["params"] = {"centralised": {"gate_chi2": 1.0}}
    with pytest.raises(ReplayMismatch, match=r"centralised\.gate_chi2"):
        replay_recording(load_recording(write(tmp_path / "e.jsonl", objs)))


# ------------------------------------------------------------------------------ the window
def test_the_window_shows_a_mismatch_in_a_banner(recorded, tmp_path):
    path, _ = recorded
    objs = objects(path)
    next(o for o in objs if o["type"] == "estimates")["digests"]["ekf"] = "0" * 64
    bad = write(tmp_path / "bad.jsonl", objs)
    app = ReplayApp(ReplaySession(load_recording(bad), FILTERS), size=(960, 600), scripted=True)

    def banner_pixels() -> int:
        x, y, w, h = app.view.area
        strip = pygame.surfarray.pixels3d(app.screen)[x:x + w, y + h - 60:y + h - 12]
        return int(np.all(strip == palette.BANNER_BG, axis=-1).sum())
    try:
        app.run(3)
        # no banner yet (the EKF's vermillion, the banner's colour, may be in the magnifier's
        # strip when it takes a bottom corner: under a hundred pixels; the banner thousands)
        assert app.session.mismatch is None and banner_pixels() < 500
        while app.session.mismatch is None and app.frames < 400:
            app.run(app.frames + 1)
        assert "estimates of filter ekf" in app.session.mismatch
        app.run(app.frames + 300)  # long after the flash: the banner stays
        assert banner_pixels() > 2000
        app.save_screenshot(str(tmp_path / "mismatch.png"))
    finally:
        app.close()
    assert main(["replay", str(bad), "--frames", "200"]) == 2


# ------------------------------------------------------------------------------ files
WRITER = textwrap.dedent("""
    import datetime, sys, time
    from beacon_sim.core.scenario import load_scenario
    from beacon_sim.io.recording import default_recording_path
    from beacon_sim.runs.recorder import Recorder
    sc = load_scenario("default")
    path = default_recording_path("same", datetime.datetime(2026, 1, 2, 3, 4, 5))
    while time.time() < float(sys.argv[1]):  # every process at once
        pass
    with Recorder(path, sc, int(sys.argv[2]), ["ekf"]) as rec:
        for k in range(1, 21):
            rec.record_tick(k, None)
        print(rec.path)
""")


def test_sessions_started_in_the_same_second_never_share_a_file(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[2]))
    start = time.time() + 3.0
    procs = [subprocess.Popen([sys.executable, "-c", WRITER, str(start), str(seed)], cwd=tmp_path,
                              env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for seed in range(6)]
    outs = [p.communicate(timeout=120) for p in procs]
    assert all(p.returncode == 0 for p in procs), [e for _, e in outs]
    paths = sorted(out.strip() for out, _ in outs)
    assert len(set(paths)) == 6, paths
    seeds = set()
    for p in paths:
        rec = load_recording(tmp_path / p)
        assert rec.complete and len(rec.ticks) == 20
        seeds.add(rec.seed)
    assert seeds == set(range(6))  # each file holds one whole session, none mixed


def test_a_new_name_is_picked_when_the_file_exists(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    path = default_recording_path("x", datetime.datetime(2026, 1, 2, 3, 4, 5))
    sc = load_scenario("default")
    first = Recorder(path, sc, 1, [])
    second = Recorder(path, sc, 1, [])  # the name was taken between the check and the open
    assert first.path == path and second.path == Path(str(path).replace(".jsonl", "-2.jsonl"))
    first.close()
    second.close()


@pytest.mark.parametrize("kind", ["file", "loop", "dangling"])
def test_a_recordings_that_is_not_a_folder_is_one_line(tmp_path, monkeypatch, capsys, kind):
    monkeypatch.chdir(tmp_path)
    if kind == "file":
        Path("recordings").write_text("x")
    elif kind == "loop":
        os.symlink("recordings", "recordings")
    else:
        os.symlink("nowhere", "recordings")
    assert main(["play", "default", "--frames", "2"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "recordings: cannot record there" in err[0] and "not a folder" in err[0]
    assert ("symlink" in err[0]) == (kind != "file")
    assert main(["play", "default", "--frames", "2", "--no-record"]) == 0
