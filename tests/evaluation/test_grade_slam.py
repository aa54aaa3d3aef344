"""A hosted SLAM filter's map comes back over the pipe with each estimate
(hosting/wire.py), judged in the grader's process; `check` judges a file's map; `grade`
scores a SLAM assignment (the path's ATE, the map's GOSPA, the joint NEES) beside the
built-in EKF-SLAM on the same seeds."""

from __future__ import annotations

import json

import numpy as np
import pytest

from beacon_sim.core.scenario import load_scenario
from beacon_sim.filters.base import LandmarkMap
from beacon_sim.hosting import conformance
from beacon_sim.hosting.landmark_check import MAX_LANDMARKS
from beacon_sim.hosting.wire import (
    MAX_MAP_BYTES,
    WireError,
    decode_landmarks,
    encode_landmarks,
    map_fault_block,
    map_problem,
)
from beacon_sim.templates import render_slam_template

#: Hostile ``landmarks()`` bodies, each appended to the SLAM template as a subclass, and the
#: words its one-line fault must contain.
HOSTILE = {
    "nan": ("lm = super().landmarks()\n"
            "        means = np.vstack([lm.means, [[np.nan, 1.0]]])\n"
            "        covs = np.concatenate([lm.covs, np.eye(2)[None]])\n"
            "        return LandmarkMap(None, means, covs)",
            "NaN or infinity"),
    "huge": ("return LandmarkMap(None, np.broadcast_to(np.zeros(2), (10**7, 2)),\n"
             "                           np.broadcast_to(np.eye(2), (10**7, 2, 2)))",
             f"10000000 landmarks, at most {MAX_LANDMARKS}"),
    "shapes": ("return LandmarkMap(None, np.zeros((2, 3)), np.zeros((2, 2, 2)))",
               "means of shape (2, 3)"),
    "raises": ("raise ValueError('no map today')", "landmarks() raised ValueError: no map today"),
    "asym": ("return LandmarkMap(None, np.zeros((1, 2)), np.array([[[1.0, 0.5], [0.0, 1.0]]]))",
             "not symmetric"),
    "loops": ("while True:\n            pass", "time limit"),
}


def hostile_file(tmp_path, kind: str):
    body, _ = HOSTILE[kind]
    path = tmp_path / f"{kind}.py"
    path.write_text(render_slam_template("MySlam", path.name)
                    + f"\n\nclass Bad(MySlam):\n    def landmarks(self):\n        {body}\n",
                    encoding="utf-8")
    return path


def _by_name(results):
    return {r.name: r for r in results}


# -- the map block on the wire -----------------------------------------------------------

def test_a_map_block_round_trips_bit_for_bit():
    rng = np.random.default_rng(4)
    a = rng.normal(size=(5, 2, 2))
    covs = a @ np.swapaxes(a, 1, 2)
    lm = LandmarkMap(np.array([3, 1, 4, 1, 5]), rng.normal(size=(5, 2)), covs)
    block = encode_landmarks(lm)
    assert isinstance(block, bytes)
    ids, means, got = decode_landmarks(block)
    assert ids is not None and ids.tolist() == [3, 1, 4, 1, 5]
    assert np.array_equal(means, lm.means) and np.array_equal(got, covs)
    assert map_problem(block)[1] is None
    nameless = encode_landmarks(LandmarkMap(None, np.zeros((0, 2)), np.zeros((0, 2, 2))))
    assert isinstance(nameless, bytes) and decode_landmarks(nameless)[0] is None


def test_the_grader_judges_a_map_it_reads_whatever_the_child_sent():
    """A child whose encoder was tampered with still cannot pass garbage: the grader checks
    the size against the head, the count, and every value."""
    good = encode_landmarks(LandmarkMap(None, np.zeros((2, 2)), np.stack([np.eye(2)] * 2)))
    assert isinstance(good, bytes)
    with pytest.raises(WireError):
        decode_landmarks(good[:-8])  # a block shorter than its head says
    with pytest.raises(WireError):
        decode_landmarks(good + b"\0" * 8)
    forged = np.int64(MAX_LANDMARKS + 1).tobytes() + np.int64(0).tobytes()
    with pytest.raises(WireError):
        decode_landmarks(forged + b"\0" * (48 * (MAX_LANDMARKS + 1)))
    nan = bytearray(good)
    nan[16:24] = np.float64(np.nan).tobytes()
    assert "NaN" in (map_problem(bytes(nan))[1] or "")
    neg = encode_landmarks(LandmarkMap(None, np.zeros((1, 2)), -np.eye(2)[None]))
    assert "not positive semi-definite" in (map_problem(neg)[1] or "")  # type: ignore[arg-type]
    assert 16 + MAX_LANDMARKS * 56 == MAX_MAP_BYTES
    # a fault sent as data (check's mode): the one line, on one line
    assert map_problem(map_fault_block("landmarks() raised KeyError: 3\nmore"))[1] == \
        "landmarks() raised KeyError: 3 more"
    with pytest.raises(WireError):
        decode_landmarks(map_fault_block("x")[:-1])


# -- check: a hosted file's map ----------------------------------------------------------

def test_check_judges_the_map_of_a_slam_file_in_its_own_process(tmp_path):
    path = tmp_path / "my_slam.py"
    path.write_text(render_slam_template("MySlam", path.name), encoding="utf-8")
    res = _by_name(conformance.run_checks(f"{path}:MySlam", load_scenario("slam_loop")))
    assert res["landmarks"].passed, res["landmarks"].message
    assert "on every step" in res["landmarks"].message and "sandbox" not in res["landmarks"].message
    # the same words as in process
    here = _by_name(conformance.run_checks(f"{path}:MySlam", load_scenario("slam_loop"), isolated=False))
    assert here["landmarks"].message == res["landmarks"].message


@pytest.mark.parametrize("kind", ["nan", "huge", "shapes", "raises", "asym"])
def test_check_fails_a_hostile_slam_files_map_with_its_message(tmp_path, kind):
    path = hostile_file(tmp_path, kind)
    res = _by_name(conformance.run_checks(f"{path}:Bad", load_scenario("slam_loop")))
    lm = res["landmarks"]
    assert not lm.passed
    assert HOSTILE[kind][1] in lm.message, lm.message
    assert lm.message.startswith("step ")
    assert res["loads"].passed and res["shapes"].passed  # the pose checks judged on their own
    assert res["runs"].passed, res["runs"].message  # as in process: the map is the map check's


def test_a_map_fault_in_process_reads_as_in_the_child(tmp_path):
    path = hostile_file(tmp_path, "nan")
    child = _by_name(conformance.run_checks(f"{path}:Bad", load_scenario("slam_loop")))["landmarks"]
    here = _by_name(conformance.run_checks(f"{path}:Bad", load_scenario("slam_loop"),
                                           isolated=False))["landmarks"]
    assert child.message == here.message
    assert json.dumps(child.message)  # one line
    assert "\n" not in child.message


# -- grade: a SLAM assignment ------------------------------------------------------------

#: A CPU-time limit far above a 15 s run of the template (about 20 ms) or EKF-SLAM (40 ms),
#: so that the looping landmarks() costs little.
SLAM_CONFIG = dict(scenarios=("slam_loop",), seeds=(0, 1), duration=15.0, time_limit=2.0)


def slam_class(tmp_path):
    """A class: the shipped template (alice), a file whose map turns NaN once it holds three
    landmarks (carol), the built-in EKF-SLAM handed in as a file (erin), and dead reckoning,
    which maps nothing (frank)."""
    from beacon_sim.cli.main import main

    folder = tmp_path / "class"
    folder.mkdir()
    assert main(["new-filter", str(folder / "alice.py"), "--slam"]) == 0
    good = render_slam_template("Carol", "carol.py")
    ret = "        return LandmarkMap(np.array(self.ids, dtype=int), self.s[3:].reshape(M, 2).copy(),"
    assert ret in good
    nan = "        if M >= 3:\n            self.s[3] = np.nan\n"
    (folder / "carol.py").write_text(good.replace(ret, nan + ret), encoding="utf-8")
    (folder / "erin.py").write_text("from beacon_sim.filters.slam.ekf_slam import EKFSLAM\n\n\n"
                                    "class Erin(EKFSLAM):\n    pass\n", encoding="utf-8")
    (folder / "frank.py").write_text("from beacon_sim.filters.gaussian.dead_reckoning "
                                     "import DeadReckoning\n\n\n"
                                     "class Frank(DeadReckoning):\n    pass\n", encoding="utf-8")
    return folder


def test_grade_scores_a_slam_class_beside_the_built_in_ekf_slam(tmp_path, capsys):
    from beacon_sim.evaluation.grading import GradeConfig, grade, write_outputs

    folder = slam_class(tmp_path)
    capsys.readouterr()
    # a fixed secret: the probe runs (drawn from it) are the same in every run of the test
    board = grade(folder, GradeConfig(**SLAM_CONFIG), jobs=2, secret=b"\x07" * 32)
    rows = {r["student"]: r for r in board.rows}
    ref = board.slam_reference["slam_loop"]
    assert ref["filter"] == "ekf_slam" and ref["ate_m"] > 0 and ref["joint_nees"] > 0
    alice = rows["alice"]
    assert not alice["failures"], alice["failures"]
    slam = alice["slam"]["slam_loop"]
    assert slam["mapped"] and slam["map_landmarks"] >= 1
    assert alice["ate_m"] == slam["ate_m"] > 0 and alice["map_gospa_m"] == slam["map_gospa_m"] > 0
    # ATE is the path's RMS position error: the row's pos RMSE on the one SLAM scenario, the
    # same number (it was the seeds' mean of per-run RMS, a different one under the same name)
    for r in (alice, rows["erin"], rows["frank"]):
        assert r["ate_m"] == pytest.approx(r["pos_rmse_m"], rel=1e-12), r["student"]
    assert alice["joint_nees"] is None  # the template has no joint()
    assert slam["reference_map_gospa_m"] == ref["map_gospa_m"]
    # the template never corrects: its path is worse than EKF-SLAM's
    assert slam["ate_m"] > ref["ate_m"]
    # the built-in EKF-SLAM handed in as a file: the reference's figures, its joint NEES too
    erin = rows["erin"]["slam"]["slam_loop"]
    assert not rows["erin"]["failures"]
    assert erin["ate_m"] == ref["ate_m"] and erin["map_gospa_m"] == ref["map_gospa_m"]
    assert erin["joint_nees"] == pytest.approx(ref["joint_nees"], rel=1e-9)
    # no landmarks(): graded on its path, its map not scored, and flagged
    frank = rows["frank"]
    assert not frank["failures"] and frank["ate_m"] > 0 and frank["map_gospa_m"] is None
    assert not frank["slam"]["slam_loop"]["mapped"]
    assert any("reports no map" in f for f in frank["flags"]), frank["flags"]
    # a bad map: switched off with the reason, no score
    r = rows["carol"]
    # both scored seeds fail; a probe (one more run, drawn from the secret) may fail too
    assert r["failed_runs"] >= len(SLAM_CONFIG["seeds"]) and r["pos_rmse_m"] is None
    assert r["ate_m"] is None and r["map_gospa_m"] is None
    assert all("landmarks(): NaN or infinity" in f["reason"] for f in r["failures"]), r["failures"]
    assert not any("reports no map" in f for f in r["flags"])  # it did, until it broke
    assert r["rank"] > rows["alice"]["rank"]
    out = tmp_path / "out"
    write_outputs(board, out)
    page = (out / "grade.html").read_text(encoding="utf-8")
    assert "map GOSPA [m]" in page and "joint NEES" in page and "ekf_slam on the same seeds" in page
    assert "The map (SLAM scenarios" in (out / "students" / "alice.html").read_text(encoding="utf-8")
    import csv

    with open(out / "grade.csv", newline="", encoding="utf-8") as fh:
        csv_rows = {r["student"]: r for r in csv.DictReader(fh)}
    assert float(csv_rows["alice"]["map_gospa_m"]) == alice["map_gospa_m"]
    assert csv_rows["carol"]["map_gospa_m"] == ""


def test_a_looping_landmarks_fails_its_run_on_its_time_limit(tmp_path):
    from beacon_sim.evaluation.grading import GradeConfig, grade

    folder = tmp_path / "class"
    folder.mkdir()
    doc = '        """The map: each landmark'
    loop = "        while len(self.ids) >= 2:\n            pass\n"
    (folder / "dave.py").write_text(render_slam_template("Dave", "dave.py").replace(doc, loop + doc),
                                    encoding="utf-8")
    board = grade(folder, GradeConfig(**{**SLAM_CONFIG, "seeds": (0,), "time_limit": 1.0}), jobs=1)
    row = board.rows[0]
    assert row["failed_runs"] == 1 and row["map_gospa_m"] is None
    assert "time limit: over 1 s of filter time" in row["failures"][0]["reason"], row["failures"]


def test_the_templates_gospa_in_grade_is_what_run_reports(tmp_path, capsys):
    """The same figure by two paths: `grade` (the file in a child, its map over the pipe)
    and `beacon-sim run slam_loop --filter FILE` (in process), same seed and length."""
    from beacon_sim.cli.main import main
    from beacon_sim.evaluation.grading import GradeConfig, grade

    folder = tmp_path / "class"
    folder.mkdir()
    assert main(["new-filter", str(folder / "alice.py"), "--slam"]) == 0
    board = grade(folder, GradeConfig(scenarios=("slam_loop",), seeds=(3,), duration=12.0), jobs=1)
    got = board.rows[0]["slam"]["slam_loop"]
    capsys.readouterr()
    assert main(["run", "slam_loop", "--filter", str(folder / "alice.py"), "--filter", "ekf_slam",
                 "--seed", "3", "--duration", "12", "--json"]) == 0
    run = json.loads(capsys.readouterr().out)["filters"]
    assert got["map_gospa_m"] == run["alice"]["slam"]["map_gospa_m"]
    assert got["ate_m"] == run["alice"]["slam"]["ate_m"]
    assert got["map_missed"] == run["alice"]["slam"]["map_missed"]
    ref = board.slam_reference["slam_loop"]
    assert ref["map_gospa_m"] == run["ekf_slam"]["slam"]["map_gospa_m"]
    assert ref["ate_m"] == run["ekf_slam"]["slam"]["ate_m"]
    assert ref["joint_nees"] == run["ekf_slam"]["slam"]["joint_nees"]


def test_the_grade_command_prints_the_map_figures_and_the_reference(tmp_path, capsys):
    from beacon_sim.cli.main import main

    folder = tmp_path / "class"
    folder.mkdir()
    assert main(["new-filter", str(folder / "alice.py"), "--slam"]) == 0
    cfg = tmp_path / "grade.toml"
    cfg.write_text('scenarios = ["slam_loop"]\nseeds = [0]\nduration = 6.0\n', encoding="utf-8")
    capsys.readouterr()
    assert main(["grade", str(folder), "--config", str(cfg), "--out", str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out
    assert "slam_loop: ATE " in out and "map GOSPA" in out
    assert "reference on slam_loop (built-in ekf_slam): ATE " in out
