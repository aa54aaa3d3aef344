"""Recording: written as the run goes, read back without executing anything, replayed bit
for bit; cut files, bad headers and tampered ticks give clear answers."""

from __future__ import annotations

import datetime
import json
from pathlib import Path

import numpy as np
import pytest
from recording_helpers import SCENARIO, live_run

from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.core.types import Control
from beacon_sim.io.recording import (
    FORMAT_VERSION,
    RecordingError,
    default_recording_path,
    load_recording,
)
from beacon_sim.runs.recorder import Recorder
from beacon_sim.runs.replay import ReplayMismatch, replay_recording


@pytest.fixture
def scenario_file(tmp_path) -> Path:
    p = tmp_path / "rec_test.toml"
    p.write_text(SCENARIO)
    return p




def truth(steps) -> np.ndarray:
    return np.array([s.true_pose for s in steps])


def test_record_then_replay_is_bit_for_bit(scenario_file, tmp_path):
    out = tmp_path / "run.jsonl"
    steps, runner, rec, sim = live_run(scenario_file, out)
    assert rec.truth_checksum == sim.truth_checksum
    recording = load_recording(out)
    assert recording.complete and not recording.warnings
    res = replay_recording(recording)
    assert res.truth_checksum == sim.truth_checksum
    assert res.extra["replay"]["checksum_status"] == "verified"
    np.testing.assert_array_equal(truth(res.steps), truth(steps))  # exact, not approximate
    for name in ("ekf", "dead_reckoning"):
        live, again = runner.tracks[name], res.runner.tracks[name]
        assert live.ticks == again.ticks
        np.testing.assert_array_equal(np.array(again.means), np.array(live.means))
        np.testing.assert_array_equal(np.array(again.covs), np.array(live.covs))
    # the user's kidnap to a pose really happened on tick 40, and was replayed
    np.testing.assert_array_equal(res.steps[39].true_pose, [3.0, 7.0, -2.5])
    # measurements too
    for a, b in zip(steps, res.steps, strict=True):
        assert len(a.measurements) == len(b.measurements)
        for ma, mb in zip(a.measurements, b.measurements, strict=True):
            np.testing.assert_array_equal(ma.z, mb.z)


def test_replay_with_another_filter_keeps_the_truth(scenario_file, tmp_path):
    out = tmp_path / "run.jsonl"
    steps, _, _, sim = live_run(scenario_file, out)
    res = replay_recording(load_recording(out), filters=["ukf"])
    assert list(res.runner.tracks) == ["ukf"]
    assert res.truth_checksum == sim.truth_checksum
    np.testing.assert_array_equal(truth(res.steps), truth(steps))
    assert len(res.runner.tracks["ukf"].means) == len(steps)


def test_recording_cut_at_random_bytes_replays_to_last_complete_tick(scenario_file, tmp_path):
    out = tmp_path / "run.jsonl"
    steps, _, _, _ = live_run(scenario_file, out)
    data = out.read_bytes()
    header_end = data.index(b"\n") + 1
    rng = np.random.default_rng(2024)
    for cut in rng.integers(header_end + 1, len(data) - 1, size=6):
        part = tmp_path / f"cut{cut}.jsonl"
        part.write_bytes(data[:cut])
        complete_lines = data[:cut].split(b"\n")[:-1]  # the text after the last newline is partial
        n_ticks = sum(1 for ln in complete_lines if json.loads(ln).get("type") == "tick")
        recording = load_recording(part)
        assert not recording.complete
        assert any("no end line" in w for w in recording.warnings)
        if not data[:cut].endswith(b"\n"):
            assert any("incomplete last line" in w for w in recording.warnings)
        res = replay_recording(recording)
        assert len(res.steps) == n_ticks
        np.testing.assert_array_equal(truth(res.steps).reshape(-1, 3), truth(steps[:n_ticks]).reshape(-1, 3))


def test_a_killed_run_leaves_at_most_one_second_unwritten(scenario_file, tmp_path):
    """Read the file while the recorder is still open (as after a kill -9: whatever was
    flushed is on disk, nothing else)."""
    out = tmp_path / "run.jsonl"
    _, _, rec, _ = live_run(scenario_file, out, ticks=137, close=False)
    on_disk = load_recording(out)
    dt = on_disk.scenario.dt
    assert (137 - len(on_disk.ticks)) * dt <= 1.0
    assert len(on_disk.ticks) >= 1
    replay_recording(on_disk)  # and what is there replays, checked tick by tick
    rec.close()


def test_header_holds_what_replay_needs(scenario_file, tmp_path):
    out = tmp_path / "run.jsonl"
    live_run(scenario_file, out, ticks=5)
    header = json.loads(out.read_text().splitlines()[0])
    assert header["version"] == FORMAT_VERSION
    assert header["scenario_toml"] == SCENARIO
    assert header["seed"] == 11 and header["dt"] == 0.1
    assert header["filters"] == ["ekf", "dead_reckoning"]
    lines = [json.loads(x) for x in out.read_text().splitlines()[1:]]
    assert [x["type"] for x in lines[-1:]] == ["end"]


@pytest.mark.parametrize("first_line, message", [
    ('{"type": "header", "format": "beacon-sim-recording", "version": 99}', "version 99"),
    ('{"type": "header", "format": "beacon-sim-rec', "corrupted header"),
    ('not json at all', "corrupted header"),
    ('{"type": "tick", "k": 1, "u": [0, 0]}', "not a beacon-sim recording"),
])
def test_bad_header_is_a_clear_error(scenario_file, tmp_path, first_line, message):
    out = tmp_path / "run.jsonl"
    live_run(scenario_file, out, ticks=5)
    lines = out.read_text().splitlines(keepends=True)
    bad = tmp_path / "bad.jsonl"
    bad.write_text(first_line + "\n" + "".join(lines[1:]))
    with pytest.raises(RecordingError, match=message) as info:
        load_recording(bad)
    assert str(bad) in str(info.value) and ":1:" in str(info.value)
    assert "\n" not in str(info.value)


def test_blank_first_line_is_a_missing_header(tmp_path):
    """A blank line 1 followed by a checkpoint line: the header is missing (exit 2 text),
    not a TypeError from reading the checkpoint against no header."""
    bad = tmp_path / "bad.jsonl"
    bad.write_text('\n{"type": "checkpoint", "k": 1, "checksum": "ab"}\n')
    with pytest.raises(RecordingError, match="corrupted header") as info:
        load_recording(bad)
    assert f"{bad}:1:" in str(info.value)


def test_header_missing_a_field_is_corrupted(scenario_file, tmp_path):
    out = tmp_path / "run.jsonl"
    live_run(scenario_file, out, ticks=5)
    lines = out.read_text().splitlines(keepends=True)
    header = json.loads(lines[0])
    del header["seed"]
    bad = tmp_path / "bad.jsonl"
    bad.write_text(json.dumps(header) + "\n" + "".join(lines[1:]))
    with pytest.raises(RecordingError, match="corrupted header: seed"):
        load_recording(bad)


def test_tampered_tick_names_the_first_tick_that_differs(scenario_file, tmp_path):
    out = tmp_path / "run.jsonl"
    live_run(scenario_file, out, ticks=60)
    lines = out.read_text().splitlines(keepends=True)
    for i, ln in enumerate(lines):
        obj = json.loads(ln)
        if obj.get("type") == "tick" and obj["k"] == 23:
            obj["u"][0] += 1e-9  # one bit of difference is enough
            lines[i] = json.dumps(obj) + "\n"
    bad = tmp_path / "tampered.jsonl"
    bad.write_text("".join(lines))
    with pytest.raises(ReplayMismatch, match="at tick 23 "):
        replay_recording(load_recording(bad))


def test_recorded_code_is_never_run(scenario_file, tmp_path):
    """A recording naming a filter file does not make replay import it."""
    marker = tmp_path / "ran.txt"
    evil = tmp_path / "evil.py"
    evil.write_text(f"open({str(marker)!r}, 'w').write('x')\nclass F: pass\n")
    out = tmp_path / "run.jsonl"
    sc = load_scenario(scenario_file)
    with Recorder(out, sc, 1, ["dead_reckoning", f"{evil}:F"], {}) as rec:
        for k in range(1, 11):
            rec.record_tick(k, Control(0.1, 0.0), [])
    res = replay_recording(load_recording(out))
    assert list(res.runner.tracks) == ["dead_reckoning"]
    assert res.extra["replay"]["skipped_filters"] == [f"{evil}:F"]
    assert not marker.exists()


def test_driver_controls_are_recorded_when_control_is_none(scenario_file, tmp_path):
    sc = load_scenario(scenario_file)
    sim = Simulation(sc, 4)
    out = tmp_path / "run.jsonl"
    with Recorder(out, sc, 4, [], {}) as rec:
        for k in range(1, 51):
            rec.record_tick(k, None, [])
            sim.step()
    res = replay_recording(load_recording(out), filters=[])
    assert res.truth_checksum == sim.truth_checksum


def test_default_recording_path(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    when = datetime.datetime(2025, 3, 4, 5, 6, 7)
    p = default_recording_path("my scenario", when)
    assert p == Path("recordings/my_scenario_20250304-050607.jsonl")
    p.parent.mkdir()
    p.write_text("")
    again = default_recording_path("my scenario", when)
    assert again == Path("recordings/my_scenario_20250304-050607-2.jsonl")
