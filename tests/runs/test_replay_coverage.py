"""What replay claims: the checksums of a recording cover the readings and
the scenario text as well as the truth (version 3: also the filter settings and estimates,
tests/runs/test_replay_verification.py; version 4: the maths, tests/runs/test_recording_maths.py);
version 1 files still replay, verified for the truth
only; a recording without checksums says 'not verified'."""

from __future__ import annotations

import hashlib
import json

import pytest

from beacon_sim.core.scenario import ScenarioError, load_scenario
from beacon_sim.io.recording import FORMAT_VERSION, RecordingError, load_recording
from beacon_sim.runs.live import Session
from beacon_sim.runs.recorder import Recorder
from beacon_sim.runs.replay import ReplayMismatch, replay_recording


@pytest.fixture
def recorded(tmp_path):
    sc = load_scenario("default")
    path = tmp_path / "run.jsonl"
    session = Session(sc, ["ekf"], 4, {}, Recorder(path, sc, 4, ["ekf"]))
    session.toggle_autopilot()
    for _ in range(60):
        session.tick()
    session.close()
    return path


def _rewrite(path, out, header=None, line=None):
    lines = path.read_text().splitlines()
    h = json.loads(lines[0])
    if header:
        header(h)
    body = []
    for ln in lines[1:]:
        obj = json.loads(ln)
        if line and line(obj) is False:
            continue
        body.append(json.dumps(obj))
    out.write_text("\n".join([json.dumps(h), *body]) + "\n")
    return out


def test_version_4_is_verified(recorded):
    assert json.loads(recorded.read_text().splitlines()[0])["version"] == FORMAT_VERSION == 4
    res = replay_recording(load_recording(recorded))
    assert res.extra["replay"]["checksum_status"] == "verified"


def test_edited_sensor_noise_is_caught(recorded, tmp_path):
    def edit(h):
        h["scenario_toml"] = h["scenario_toml"].replace("range_std = 0.05", "range_std = 0.5")
    naive = _rewrite(recorded, tmp_path / "naive.jsonl", edit)
    with pytest.raises(RecordingError, match="scenario was edited"):
        load_recording(naive)

    def edit_and_rehash(h):
        edit(h)
        h["scenario_sha256"] = hashlib.sha256(h["scenario_toml"].encode()).hexdigest()
    clever = _rewrite(recorded, tmp_path / "clever.jsonl", edit_and_rehash)
    with pytest.raises(ReplayMismatch, match="readings checksum"):
        replay_recording(load_recording(clever))


def test_moved_beacon_is_caught(recorded, tmp_path):
    def edit(h):
        h["scenario_toml"] = h["scenario_toml"].replace("x = 1.5, y = 1.5", "x = 1.6, y = 1.5")
        h["scenario_sha256"] = hashlib.sha256(h["scenario_toml"].encode()).hexdigest()
    with pytest.raises(ReplayMismatch):
        replay_recording(load_recording(_rewrite(recorded, tmp_path / "b.jsonl", edit)))


def test_version_1_replays_verified_for_the_truth_only(recorded, tmp_path):
    def v1(h):
        h["version"] = 1
        del h["scenario_sha256"]

    def strip(obj):
        obj.pop("r", None)
        obj.pop("readings_checksum", None)
        obj.pop("estimates", None)
        return obj["type"] not in ("filters", "estimates")
    old = _rewrite(recorded, tmp_path / "v1.jsonl", v1, strip)
    status = replay_recording(load_recording(old)).extra["replay"]["checksum_status"]
    assert status == ("not verified: the readings and filter settings (a version 1 file records "
                      "neither); the truth verified")


def test_no_checksums_is_not_verified(recorded, tmp_path):
    def v2(h):  # (a version 3 file without its checkpoint lines is refused as edited)
        h["version"] = 2
        h["scenario_sha256"] = h["scenario_sha256"][:16]

    def strip(obj):
        obj.pop("h", None)
        obj.pop("r", None)
        return obj["type"] == "tick"
    bare = _rewrite(recorded, tmp_path / "bare.jsonl", v2, line=strip)
    status = replay_recording(load_recording(bare)).extra["replay"]["checksum_status"]
    assert status.startswith("not verified")


def test_a_scenario_may_not_name_code(tmp_path):
    text = (tmp_path / "x.toml")
    base = (load_scenario("default").source)
    src = open(base, encoding="utf-8").read()
    for spec in ("evil.py:Evil", "/abs/evil.py:Evil", "os:system", "a=evil.py:Evil"):
        text.write_text(src + f'\ndefault_filters = ["{spec}"]\n' if "default_filters" not in src
                        else src.replace("default_filters", f'default_filters = ["{spec}"]\n#', 1))
        with pytest.raises(ScenarioError, match="may not name a file or module"):
            load_scenario(text)
