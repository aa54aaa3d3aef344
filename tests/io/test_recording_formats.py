"""Recording formats kept: one writer and one reader over N robots.

``tests/data/old_recordings`` holds files written by every earlier writer: versions 1 and 2
(single robot), version 2 (a team), and version 3 of a single robot and of a team written by
the two writers that existed before 0.3.0 (``Recorder`` and ``TeamRecorder``), from the
scripted sessions below. The one writer of today writes the same lines from the same
session: the same kinds in the same order, the same ticks, drivers and user commands, the
same header. (Byte for byte until format version 4: since then the truth uses the portable maths,
so its numbers and checksums differ in the last bits, and version 4 adds the maths
fingerprint and the estimates' values.) Every file loads and replays from its recorded
commands, with a status that says what it verified (tests/runs/test_replay_verification.py).
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest

from beacon_sim.core.scenario import load_scenario, load_team_scenario, team_of_one
from beacon_sim.core.types import Control
from beacon_sim.io.recording import load_recording
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
#: The filters of the scripted single-robot session, and its --set overrides.
SOLO_FILTERS = ["ekf", "ukf", "dead_reckoning"]
SOLO_PARAMS = {"ekf": {"gate_chi2": 9.0}}
#: The filters of the scripted team session (a team filter, a single-robot filter on every
#: robot, and the joint EKF).
TEAM_FILTERS = ["independent", "independent:ukf", "centralised"]
TEAM_PARAMS = {"centralised": {"gate_chi2": 16.0}}
#: Ticks of each scripted session.
SOLO_TICKS = 240
TEAM_TICKS = 200


def drive_solo(session) -> None:
    """A single-robot session driven by a fixed script: the autopilot, then the keyboard,
    a kidnap to a pose, a random kidnap, a filter reset, a show / hide, a global reset."""
    session.toggle_autopilot()
    for k in range(1, SOLO_TICKS + 1):
        if k == 60:
            session.drive("w")  # the keyboard takes over from the autopilot
        if k == 70:
            session.drive("a")
        if k == 80:
            session.command({"kind": "kidnap", "pose": [2.0, 1.5, 0.25]})
        if k == 120:
            session.command({"kind": "toggle", "filter": "ukf"})
        if k == 130:
            session.command({"kind": "kidnap"})
        if k == 150:
            session.command({"kind": "reset"})
        if k == 170:
            session.drive("d")
        if k == 200:
            session.command({"kind": "global_reset"})
        session.tick()


def drive_team(session) -> None:
    """A team session driven by a fixed script: robot 0 by keyboard, robot 1 on its own
    driver (autopilot), kidnaps of each to a pose and at random, a filter reset, a show /
    hide."""
    for k in range(1, TEAM_TICKS + 1):
        if k == 5:
            session.drive("w")
        if k == 40:
            session.command({"kind": "kidnap", "pose": [3.0, 2.0, 0.5]})
        if k == 60:
            session.next_robot()
            session.toggle_autopilot()
        if k == 90:
            session.command({"kind": "kidnap"})
        if k == 110:
            session.command({"kind": "toggle", "filter": "centralised"})
        if k == 120:
            session.command({"kind": "reset"})
        if k == 150:
            session.drive("a")  # takes over from the autopilot
        session.tick()


def assert_subset(old, new, where: str) -> None:
    """Every parameter of ``old`` is in ``new`` with the same value (members too)."""
    if isinstance(old, dict):
        for k, v in old.items():
            assert k in new, f"{where}.{k}"
            assert_subset(v, new[k], f"{where}.{k}")
    elif isinstance(old, list):
        assert len(old) == len(new), where
        for i, (a, b) in enumerate(zip(old, new, strict=True)):
            assert_subset(a, b, f"{where}[{i}]")
    else:
        assert old == new, where


def header_free(lines: list[str]) -> list[str]:
    """The lines with the header's ``created`` and ``program_version`` blanked (when and by
    which release a file was written)."""
    head = json.loads(lines[0])
    head["created"] = head["program_version"] = ""
    head["scenario_source"] = Path(head["scenario_source"]).name
    return [json.dumps(head), *lines[1:]]


#: What version 4 adds to a header, and the header fields of when, by which
#: release and from which folder a file was written.
NEW_OR_LOCAL = ("version", "maths", "maths_description", "created", "program_version",
                "scenario_source", "scenario_toml", "scenario_sha256")


def shape(line: str) -> tuple:
    """What a line says beyond its numbers: its kind and keys; a tick's number, driven robot,
    autopilot and user commands (the numbers of the truth, the checksums, digests and
    estimate values are the maths')."""
    obj = json.loads(line)
    keys = tuple(sorted(set(obj) - {"values"}))
    if obj["type"] == "tick":
        return keys, obj["k"], obj.get("d"), obj.get("a"), obj.get("c")
    return (keys,)


def scripted_recording(kind: str, path: Path) -> Path:
    """The scripted session of ``kind`` ("solo": SOLO_*, on sparse_kidnap with seed 11;
    "team": TEAM_*, on team_sparse with seed 13) recorded by today's writer to ``path``."""
    if kind == "solo":
        sc = load_scenario("sparse_kidnap")
        rec = Recorder(path, sc, 11, SOLO_FILTERS, SOLO_PARAMS)
        session = Session(sc, SOLO_FILTERS, 11, SOLO_PARAMS, rec)
        drive_solo(session)
    else:
        team = load_team_scenario("team_sparse")
        rec = Recorder(path, team, 13, TEAM_FILTERS, TEAM_PARAMS)
        session = Session(team, TEAM_FILTERS, 13, TEAM_PARAMS, rec)
        drive_team(session)
    session.close()
    return rec.path


@pytest.fixture(scope="module")
def scripted(tmp_path_factory):
    """The scripted sessions recorded by today's writer, once: ``scripted("solo")``."""
    made: dict[str, Path] = {}

    def get(kind: str) -> Path:
        if kind not in made:
            made[kind] = scripted_recording(kind, tmp_path_factory.mktemp(kind) / "run.jsonl")
        return made[kind]
    return get


@pytest.mark.parametrize(("kind", "old"), [("solo", "v3_sparse_kidnap.jsonl"),
                                           ("team", "v3_team_sparse.jsonl")])
def test_the_one_writer_writes_what_the_two_wrote(scripted, kind, old):
    """Recorder (one robot) and TeamRecorder (a team) wrote the files under OLD before
    0.3.0; the one Recorder writes the same lines from the same scripted session (the
    same header, the same ticks and commands, the same kinds of line in the same order)."""
    new = scripted(kind).read_text(encoding="utf-8").splitlines()
    before = (OLD / old).read_text(encoding="utf-8").splitlines()
    assert len(new) == len(before)
    assert ('"kind":"team"' in new[0]) == (kind == "team")
    assert [shape(line) for line in new[2:]] == [shape(line) for line in before[2:]]
    head, head_before = json.loads(new[0]), json.loads(before[0])
    assert head["version"] == 4 and head_before["version"] == 3
    assert {k: v for k, v in head.items() if k not in NEW_OR_LOCAL} == \
        {k: v for k, v in head_before.items() if k not in NEW_OR_LOCAL}
    assert head["scenario_source"] == Path(head_before["scenario_source"]).stem  # shipped: its name
    # the scenario file as it was shipped: the same scenario, its comments since reworded
    assert tomllib.loads(head["scenario_toml"]) == tomllib.loads(head_before["scenario_toml"])
    # line 2, the filters' effective parameters, grows by the parameters added to the
    # filters since (the association parameters, at their defaults)
    added = json.loads(new[1])["filters"], json.loads(before[1])["filters"]
    assert added[0].keys() == added[1].keys()
    for name, entry in added[1].items():
        assert_subset(entry["params"], added[0][name]["params"], name)


def test_every_old_recording_reads_as_a_team_and_replays():
    """Every file under OLD (versions 1 to 3, one robot and teams) loads with the one reader
    (a single robot's file as a team of one) and replays from its recorded commands, every
    tick of it (its status: tests/runs/test_replay_verification.py)."""
    files = sorted(OLD.glob("*.jsonl"))
    assert {f.name for f in files} >= {"v1_sparse_kidnap.jsonl", "v2_sparse_kidnap.jsonl",
                                       "v2_team_sparse.jsonl", "v3_sparse_kidnap.jsonl",
                                       "v3_team_sparse.jsonl"}
    for f in files:
        rec = load_recording(f)
        assert rec.complete, f.name
        team_file = "team" in f.name
        assert rec.is_team == team_file and rec.team.solo == (not team_file)
        assert rec.n_robots == (3 if team_file else 1)
        if not team_file:
            assert rec.scenario is rec.team.robots[0].scenario
            assert rec.scenario.name == "sparse_kidnap" and rec.team.seed == rec.seed
        out = replay_recording(rec)
        assert len(out.steps) == len(rec.ticks) == rec.end["ticks"], f.name


def test_a_team_of_one_is_recorded_in_a_single_robots_format(tmp_path):
    """Recorder given a Scenario, or the team of one made from it, writes the same file; the
    single robot's call form (tick, control, commands) and the N-robot one (tick, driven,
    control, autopilot, commands) record the same tick."""
    sc = load_scenario("default")
    files = []
    for i, (scenario, new_form) in enumerate([(sc, True), (team_of_one(sc), True), (sc, False)]):
        path = tmp_path / f"{i}.jsonl"
        with Recorder(path, scenario, 5, ["ekf"]) as rec:
            for k in range(1, 31):
                control = Control(0.2, 0.1 * (k % 3))
                cmds = [{"kind": "kidnap", "pose": [1.0, 1.0, 0.0]}] if k == 10 else []
                if new_form:
                    rec.record_tick(k, 0, control, False, cmds)
                else:
                    rec.record_tick(k, control, cmds)
        files.append(header_free(path.read_text(encoding="utf-8").splitlines()))
    assert files[0] == files[1] == files[2]
    assert all('"d"' not in line and '"poses"' not in line for line in files[0])
    rec = load_recording(tmp_path / "0.jsonl")
    assert not rec.is_team and rec.ticks[9].commands == [{"kind": "kidnap", "pose": [1.0, 1.0, 0.0]}]
    assert replay_recording(rec).extra["replay"]["checksum_status"] == \
        "not verified: the filter settings and estimates (not recorded); truth and readings verified"


def test_a_single_robot_command_is_refused_in_a_teams_file_and_back(tmp_path):
    """The two formats keep their own commands: a team's kidnap names a robot, a single
    robot's has none and may be a global reset."""
    team = load_team_scenario("team_sparse")
    with Recorder(tmp_path / "t.jsonl", team, 2, ["independent"]) as rec, \
            pytest.raises(ValueError, match="unknown team command 'global_reset'"):
        rec.record_tick(1, 0, Control(), False, [{"kind": "global_reset"}])
    with Recorder(tmp_path / "s.jsonl", load_scenario("default"), 2, ["ekf"]) as rec:
        rec.record_tick(1, 0, Control(), False, [{"kind": "global_reset"}])
        with pytest.raises(ValueError, match="unknown user command"):
            rec.record_tick(2, 0, Control(), False, [{"kind": "exec"}])


@pytest.mark.parametrize("kind", ["solo", "team"])
def test_the_one_replay_session_replays_either_kind_and_seeks_back_exactly(scripted, kind):
    """ReplaySession is the live Session over the file's robots (a single robot's: a team of
    one): played to the end it is "verified"; seeking back and forward again lands on the
    same truth and estimates as the straight run."""
    rec = load_recording(scripted(kind))
    s = ReplaySession(rec, recorded_filter_specs(rec, None)[0], recorded_params(rec, None))
    assert isinstance(s, Session) and s.n_robots == rec.n_robots and s.team.solo == (not rec.is_team)
    s.seek(120)
    straight = (s.sim.truth_checksum, s.poses.copy(),
                {n: s.filters_run.latest(n)[0].copy() for n in s.names})
    s.seek(s.total_ticks)
    assert s.at_end and s.mismatch is None
    assert s.checksum_status() == "verified"
    assert s.sim.truth_checksum == rec.end["checksum"]
    s.seek(40)
    s.seek(120)
    assert s.sim.truth_checksum == straight[0] and np.array_equal(s.poses, straight[1])
    for n, mean in straight[2].items():
        assert np.array_equal(s.filters_run.latest(n)[0], mean), n


def test_an_edited_team_estimate_is_named_in_the_window_replay(scripted, tmp_path):
    """The window's replay checks a team's estimate digests as the headless one does: an
    edited digest is a MISMATCH naming the filter."""
    lines = scripted("team").read_text(encoding="utf-8").splitlines()
    k = next(i for i, line in enumerate(lines) if '"type":"estimates"' in line)
    obj = json.loads(lines[k])
    obj["digests"]["independent:ukf"] = "0" * 64
    lines[k] = json.dumps(obj, separators=(",", ":"))
    bad = tmp_path / "edited.jsonl"
    bad.write_text("\n".join(lines) + "\n", encoding="utf-8")
    rec = load_recording(bad)
    s = ReplaySession(rec, recorded_filter_specs(rec, None)[0], recorded_params(rec, None))
    s.seek(s.total_ticks)
    assert s.mismatch is not None and "independent:ukf" in s.mismatch
    assert s.checksum_status().startswith("MISMATCH")
    with pytest.raises(ReplayMismatch, match="the estimates of filter independent:ukf"):
        replay_recording(rec)


@pytest.mark.parametrize(("drop", "verified"), [("joseph", True), ("gate_chi2", False)])
def test_a_parameter_the_file_lacks_is_an_edit_unless_at_its_default(scripted, tmp_path, drop,
                                                                     verified):
    """A file written before a filter gained a parameter lacks it: at its default it is not
    an edit (the digests still check the estimates); a lacking parameter whose value is not
    the default (the ekf's gate_chi2 was set to 9.0 by --set) is named."""
    lines = scripted("solo").read_text(encoding="utf-8").splitlines()
    obj = json.loads(lines[1])
    del obj["filters"]["ekf"]["params"][drop]
    lines[1] = json.dumps(obj, separators=(",", ":"))
    path = tmp_path / "lacking.jsonl"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    if verified:
        out = replay_recording(load_recording(path))
        assert out.extra["replay"]["checksum_status"] == "verified"
    else:
        with pytest.raises(ReplayMismatch, match=r"ekf\.gate_chi2 recorded as '\(absent\)', but 9\.0"):
            replay_recording(load_recording(path))
