"""Recordings verify anywhere: a recording names the maths that made it and stores
its filters' estimate values, so a replay on other maths checks the inputs bit for bit and
the estimates within a stated tolerance; an edit of the inputs is named everywhere; a file
made before says honestly what it cannot prove; no recording holds a folder.

"Other maths" here is numpy with its AVX-512 kernels switched off (``NPY_DISABLE_CPU_FEATURES``)
in a subprocess: on a machine with AVX-512 its fingerprint differs from this process's. On a
machine without AVX-512 the two are the same maths and the cross-maths tests are skipped.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from beacon_sim.cli.main import main
from beacon_sim.core.maths_fingerprint import maths_description, maths_fingerprint
from beacon_sim.core.scenario import load_scenario, load_team_scenario
from beacon_sim.io.recording import RecordingError, estimate_values, load_recording
from beacon_sim.runs.live import Session
from beacon_sim.runs.recorder import Recorder
from beacon_sim.runs.replay import ReplayMismatch, ReplaySession, replay_recording
from beacon_sim.runs.replay_maths import COV_RTOL, MEAN_TOL, estimate_difference

#: numpy's AVX-512 kernels off: the other maths of this machine.
OTHER_MATHS = {"NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR"}
#: The recorded filters: the EKF (bit for bit on either maths) and the grid filter (its
#: numpy kernels round differently: its estimates differ in the last bits).
FILTERS = ["ekf", "histogram"]
TICKS = 60
OLD = Path(__file__).parents[1] / "data" / "old_recordings"

RECORD = textwrap.dedent("""
    import sys
    from beacon_sim.core.scenario import load_scenario
    from beacon_sim.runs.live import Session
    from beacon_sim.runs.recorder import Recorder
    path, filters, ticks = sys.argv[1], sys.argv[2].split(","), int(sys.argv[3])
    sc = load_scenario("default")
    s = Session(sc, filters, 4, {}, Recorder(path, sc, 4, filters, {}))
    s.toggle_autopilot()
    for k in range(1, ticks + 1):
        if k == 15:
            s.command({"kind": "kidnap", "pose": [3.0, 2.0, 0.5]})
        s.tick()
    s.close()
""")


def record_here(path: Path, filters=FILTERS, ticks: int = TICKS) -> Path:
    """The session RECORD describes, recorded in this process."""
    sc = load_scenario("default")
    s = Session(sc, list(filters), 4, {}, Recorder(path, sc, 4, list(filters), {}))
    s.toggle_autopilot()
    for k in range(1, ticks + 1):
        if k == 15:
            s.command({"kind": "kidnap", "pose": [3.0, 2.0, 0.5]})
        s.tick()
    s.close()
    return path


def other_env() -> dict[str, str]:
    return {**os.environ, **OTHER_MATHS, "SDL_VIDEODRIVER": "dummy", "SDL_AUDIODRIVER": "dummy",
            "PYTHONPATH": str(Path(__file__).resolve().parents[2])}


def run_other(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, *args], cwd=cwd, env=other_env(), capture_output=True,
                          text=True, timeout=120)


@pytest.fixture(scope="module")
def other_fingerprint(tmp_path_factory) -> str:
    """The fingerprint of the other maths; skips when it is this process's (no AVX-512)."""
    out = run_other(["-c", "from beacon_sim.core.maths_fingerprint import maths_fingerprint as f;"
                     " print(f())"], tmp_path_factory.mktemp("fp"))
    fp = out.stdout.strip()
    if fp == maths_fingerprint():
        pytest.skip("this machine's maths do not change with AVX-512 off (no AVX-512)")
    return fp


@pytest.fixture(scope="module")
def made_there(tmp_path_factory, other_fingerprint) -> Path:
    """A recording made in a subprocess on the other maths."""
    path = tmp_path_factory.mktemp("there") / "there.jsonl"
    out = run_other(["-c", RECORD, str(path), ",".join(FILTERS), str(TICKS)], path.parent)
    assert out.returncode == 0, out.stderr
    return path


@pytest.fixture(scope="module")
def made_here(tmp_path_factory) -> Path:
    return record_here(tmp_path_factory.mktemp("here") / "here.jsonl")


def objects(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def write(path: Path, objs: list[dict]) -> Path:
    path.write_text("".join(json.dumps(o) + "\n" for o in objs))
    return path


def status_of(path: Path) -> str:
    return replay_recording(load_recording(path)).extra["replay"]["checksum_status"]


def replay_there(path: Path) -> subprocess.CompletedProcess:
    """``beacon-sim replay FILE --headless --json`` on the other maths."""
    return run_other(["-m", "beacon_sim", "replay", str(path), "--headless", "--json"], path.parent)


def edit_command(objs: list[dict]) -> list[dict]:
    """The tick 20 command changed, its checksums left as they were."""
    next(o for o in objs if o["type"] == "tick" and o["k"] == 20)["u"][0] += 0.05
    return objs


def edit_reading(objs: list[dict]) -> list[dict]:
    """The sensor's noise changed in the stored scenario, its checksum recomputed (as anyone
    can): the readings differ from tick 1 on."""
    import hashlib
    h = objs[0]
    h["scenario_toml"] = h["scenario_toml"].replace("range_std = 0.05", "range_std = 0.06")
    assert "range_std = 0.06" in h["scenario_toml"]
    h["scenario_sha256"] = hashlib.sha256(h["scenario_toml"].encode()).hexdigest()
    return objs


# ------------------------------------------------------------------------------ the header
def test_the_header_names_the_maths_and_no_folder(tmp_path, made_here):
    """A header holds this machine's maths fingerprint and description, a shipped scenario
    by its name and a user's file by its file name: no folder of the machine that made it."""
    head = objects(made_here)[0]
    assert head["maths"] == maths_fingerprint() and head["maths_description"] == maths_description()
    assert head["scenario_source"] == "default"
    folder = tmp_path / "my" / "scenarios"
    folder.mkdir(parents=True)
    mine = folder / "room.toml"
    mine.write_text(Path(load_scenario("default").source).read_text())
    sc = load_scenario(mine)
    with Recorder(tmp_path / "mine.jsonl", sc, 1, ["ekf"]) as rec:
        rec.record_tick(1, None)
    text = (tmp_path / "mine.jsonl").read_text()
    assert json.loads(text.splitlines()[0])["scenario_source"] == "room.toml"
    assert str(tmp_path) not in text and str(Path.home()) not in text
    assert str(Path(__file__).resolve().parents[2]) not in made_here.read_text()
    rec = load_recording(tmp_path / "mine.jsonl")
    assert rec.maths == maths_fingerprint() and rec.scenario.name == sc.name


def test_an_export_of_an_old_recording_holds_no_folder(tmp_path, capsys):
    """An old file's header holds the path it was recorded from; its export does not."""
    old = OLD / "v2_sparse_kidnap.jsonl"
    assert "/scenarios/sparse_kidnap.toml" in old.read_text().splitlines()[0]
    out = tmp_path / "x.npz"
    assert main(["export", str(old), "--out", str(out), "--filter", "dead_reckoning"]) == 0
    with np.load(out) as z:
        header = json.loads(str(z["header_json"]))
    assert header["scenario_source"] == "sparse_kidnap.toml"
    assert "/" not in json.dumps({k: v for k, v in header.items() if k != "scenario_toml"})


@pytest.mark.parametrize(("edit", "why"), [
    (lambda h: h.pop("maths"), "maths = None"),
    (lambda h: h.update(maths="AVX512"), "maths = 'AVX512'"),
    (lambda h: h.update(maths_description=["x"]), "maths_description"),
])
def test_a_bad_maths_key_is_a_corrupted_header(made_here, tmp_path, edit, why):
    objs = objects(made_here)
    edit(objs[0])
    with pytest.raises(RecordingError, match="corrupted header") as info:
        load_recording(write(tmp_path / "bad.jsonl", objs))
    assert why in str(info.value) and ":1:" in str(info.value)


# ------------------------------------------------------------------------------ values
def test_every_estimates_line_holds_the_estimates_themselves(tmp_path):
    """Beside the digests, each estimates line and the end line hold every filter's estimate
    of that tick (mean and covariance's upper triangle, per robot) that reads back bit for
    bit: a single robot's and a team's."""
    sc = load_scenario("default")
    path = tmp_path / "solo.jsonl"
    s = Session(sc, FILTERS, 2, {}, Recorder(path, sc, 2, FILTERS))
    s.toggle_autopilot()
    seen = {}
    for _ in range(45):
        step = s.tick()
        seen[step.tick] = {n: estimate_values(*s.filters_run.latest(n)) for n in FILTERS}
    s.close()
    lines = [o for o in objects(path) if o["type"] in ("estimates", "end")]
    assert [o.get("k", o.get("ticks")) for o in lines] == [20, 40, 45]
    for o in lines:
        assert o["values"] == seen[o.get("k", o.get("ticks"))]
        assert all(len(v) == 9 for v in o["values"].values())
    team = load_team_scenario("team_sparse")
    path = tmp_path / "team.jsonl"
    s = Session(team, ["independent", "centralised"], 2, {},
                Recorder(path, team, 2, ["independent", "centralised"]))
    for _ in range(20):
        s.tick()
    s.close()
    end = objects(path)[-1]
    assert set(end["values"]) == {"independent", "centralised"}
    assert all(len(v) == 9 * 3 for v in end["values"].values())
    means, covs = s.estimates("centralised")
    assert end["values"]["centralised"] == estimate_values(means, covs)


def test_an_edited_estimate_value_is_named_on_the_same_maths(made_here, tmp_path):
    """The digests prove what the filters computed; a stored value that is not it is an
    edit (on the same maths, and wherever the digest matches)."""
    objs = objects(made_here)
    next(o for o in objs if o["type"] == "estimates")["values"]["ekf"][0] += 1e-12
    with pytest.raises(ReplayMismatch, match=r"the estimate values of filter ekf.*edited"):
        replay_recording(load_recording(write(tmp_path / "v.jsonl", objs)))


# ------------------------------------------------------------------------------ same maths
def test_the_same_maths_verify_bit_for_bit(made_here):
    out = replay_recording(load_recording(made_here))
    assert out.extra["replay"]["checksum_status"] == "verified"
    assert out.extra["replay"]["maths"]["same"] is True
    assert out.extra["replay"]["estimate_differences"] == {}


@pytest.mark.parametrize("edit", [edit_command, edit_reading])
def test_an_edited_input_is_an_edit_on_the_same_maths(made_here, tmp_path, edit):
    with pytest.raises(ReplayMismatch, match="was it edited"):
        replay_recording(load_recording(write(tmp_path / "e.jsonl", edit(objects(made_here)))))


# ------------------------------------------------------------------------------ other maths
def test_made_on_other_maths_it_verifies_here_within_the_tolerance(made_there, other_fingerprint,
                                                                   capsys):
    """A recording made with AVX-512 off, replayed here: the inputs bit for bit, the EKF
    still bit for bit, the grid filter within the tolerance; the status says so, exit 0."""
    rec = load_recording(made_there)
    assert rec.maths == other_fingerprint != maths_fingerprint()
    out = replay_recording(rec)
    info = out.extra["replay"]
    status = info["checksum_status"]
    assert status.startswith(f"verified; recorded on a machine whose maths differs "
                             f"({rec.maths_description}; here {maths_description()}): inputs "
                             "verified bit for bit, estimates within the tolerance (1e-6 m"), status
    assert info["maths"] == {"recorded": other_fingerprint, "here": maths_fingerprint(),
                             "recorded_description": rec.maths_description,
                             "here_description": maths_description(), "same": False}
    # the EKF bit for bit; the grid filter's digest differs, its values within the tolerance
    assert set(info["estimate_differences"]) == {"histogram"}
    diff = info["estimate_differences"]["histogram"]
    assert diff["position_m"] <= MEAN_TOL and diff["heading_rad"] <= MEAN_TOL
    assert diff["cov_rel"] <= COV_RTOL
    assert main(["replay", str(made_there), "--headless"]) == 0
    assert status in capsys.readouterr().out


def test_made_here_it_verifies_on_other_maths_within_the_tolerance(made_here, other_fingerprint):
    done = replay_there(made_here)
    assert done.returncode == 0, done.stderr
    info = json.loads(done.stdout)["replay"]
    assert info["maths"]["here"] == other_fingerprint and info["maths"]["same"] is False
    assert info["checksum_status"].startswith("verified; recorded on a machine whose maths "
                                              f"differs ({maths_description()}; here ")
    assert "inputs verified bit for bit, estimates within the tolerance" in info["checksum_status"]
    assert set(info["estimate_differences"]) == {"histogram"}


@pytest.mark.parametrize("edit", [edit_command, edit_reading])
def test_an_edited_input_is_an_edit_on_other_maths_too(made_there, made_here, tmp_path, edit):
    """The truth and readings are the same bits on every machine: an edited command or
    reading is named as an edit whichever maths made the file or replays it."""
    there = write(tmp_path / "there.jsonl", edit(objects(made_there)))
    with pytest.raises(ReplayMismatch, match="was it edited"):
        replay_recording(load_recording(there))
    here = write(tmp_path / "here.jsonl", edit(objects(made_here)))
    done = replay_there(here)
    assert done.returncode == 2 and "was it edited" in done.stderr, done.stderr


def test_estimates_beyond_the_tolerance_on_other_maths_are_not_verified(made_there, tmp_path):
    """On other maths a filter's estimates beyond the tolerance are not called an edit (a
    filter that makes a discrete choice can move a hypothesis on one rounding) but are not
    verified either: the status names the filter, the difference and the tick; exit 0. One
    within the tolerance passes."""
    objs = objects(made_there)
    for o in objs:
        if o["type"] in ("estimates", "end"):
            o["values"]["histogram"][1] += 1e-3     # beyond: 1 mm
            o["values"]["ekf"][0] += 1e-9           # within (its digest: edited too)
            o["digests" if o["type"] == "estimates" else "estimates"]["ekf"] = "0" * 64
    path = write(tmp_path / "beyond.jsonl", objs)
    status = status_of(path)
    assert status.startswith("not verified: histogram: not verified (different maths): its "
                             "estimates differ from the recorded ones by 0.001 m"), status
    assert ("at tick 20, beyond the tolerance; truth, readings, filter settings and the other "
            "estimates verified; recorded on a machine whose maths differs") in status
    assert "the other estimates within the tolerance" in status
    assert "edited" not in status
    assert main(["replay", str(path), "--headless"]) == 0


def test_other_filters_on_other_maths_verify_the_truth_and_readings(made_there):
    status = replay_recording(load_recording(made_there), ["ukf"]).extra["replay"]["checksum_status"]
    assert status == ("not verified: the estimates (other filters or parameters than the "
                      "recorded ones); truth and readings verified; recorded on a machine "
                      f"whose maths differs ({load_recording(made_there).maths_description}; "
                      f"here {maths_description()})")


def test_the_window_gives_the_same_verdict_on_other_maths(made_there):
    rec = load_recording(made_there)
    s = ReplaySession(rec, FILTERS, {})
    s.seek(s.total_ticks)
    assert s.mismatch is None
    assert s.checksum_status() == status_of(made_there)


# ------------------------------------------------------------------------------ old files
def as_version_3(objs: list[dict]) -> list[dict]:
    """A file as beacon-sim wrote it before format version 4: no maths, no estimate values."""
    objs[0]["version"] = 3
    del objs[0]["maths"], objs[0]["maths_description"]
    for o in objs:
        o.pop("values", None)
    return objs


def test_a_file_that_does_not_name_its_maths_is_never_called_edited(made_here, tmp_path):
    """Without the maths in the header, a replay cannot tell another machine's rounding (or
    the maths changed since) from an edit: a truth that differs is "not verified", the
    replay runs to its end (exit 0); estimates that differ are listed as not verified."""
    path = write(tmp_path / "v3.jsonl", as_version_3(objects(made_here)))
    assert status_of(path) == "verified"
    objs = edit_command(as_version_3(objects(made_here)))
    cmd = write(tmp_path / "v3-cmd.jsonl", objs)
    out = replay_recording(load_recording(cmd))
    assert len(out.steps) == TICKS
    assert out.extra["replay"]["checksum_status"] == (
        "not verified: made before beacon-sim's portable maths (or on a machine whose maths "
        "differs), so its truth and readings cannot be verified here (the replay first differs "
        "at tick 20, t = 1 s, checked against its truth checksum); replayed from its recorded "
        "commands")
    assert main(["replay", str(cmd), "--headless"]) == 0
    s = ReplaySession(load_recording(cmd), FILTERS, {})
    s.seek(s.total_ticks)
    assert s.mismatch is None and s.checksum_status() == out.extra["replay"]["checksum_status"]
    objs = as_version_3(objects(made_here))
    next(o for o in objs if o["type"] == "estimates")["digests"]["histogram"] = "0" * 64
    assert status_of(write(tmp_path / "v3-est.jsonl", objs)) == (
        "not verified: histogram: its estimates differ from the recorded ones: not verified "
        "(the file does not say which maths made it); truth, readings, filter settings and the "
        "other estimates verified")


# ------------------------------------------------------------------------------ tolerance
def test_the_difference_of_two_estimates():
    """Position and heading (wrapped at +-pi) within 1e-6, the covariance relative to the
    replay's own scale (an edited recorded value cannot widen it), NaN only against NaN."""
    a = estimate_values(np.array([1.0, 2.0, math.pi - 1e-9]), np.diag([4.0, 1.0, 0.01]))
    b = estimate_values(np.array([1.0, 2.0 + 5e-7, -math.pi + 1e-9]), np.diag([4.0, 1.0, 0.01]))
    d = estimate_difference(a, b)
    assert d.within and d.position_m == pytest.approx(5e-7) and d.heading_rad < 3e-9
    c = list(b)
    c[4] = 1e-6 * 2.0 * 1.5   # Pxy off by 1.5e-6 of sqrt(Pxx Pyy) = 2
    assert not estimate_difference(c, b).within
    assert estimate_difference(c, b).cov_rel == pytest.approx(1.5e-6)
    huge = list(b)
    huge[3] = 1e300            # an edited Pxx does not become its own scale
    assert not estimate_difference(huge, b).within
    assert not estimate_difference(a[:9], a + a).within
    nan = list(a)
    nan[0] = math.nan
    assert estimate_difference(nan, nan).within and not estimate_difference(nan, a).within
