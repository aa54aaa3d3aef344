"""Issue 29/30: a hosted SLAM filter's map comes back over the pipe with each estimate
(filters/wire.py), judged in the grader's process; `check` judges a file's map; `grade`
scores a SLAM assignment (the path's ATE, the map's GOSPA, the joint NEES) beside the
built-in EKF-SLAM on the same seeds."""

from __future__ import annotations

import json

import numpy as np
import pytest

from beacon_sim.core.scenario import load_scenario
from beacon_sim.filters import conformance
from beacon_sim.filters.base import LandmarkMap
from beacon_sim.filters.landmark_check import MAX_LANDMARKS
from beacon_sim.filters.slam_template import render_slam_template
from beacon_sim.filters.wire import (
    MAX_MAP_BYTES,
    WireError,
    decode_landmarks,
    encode_landmarks,
    map_problem,
)

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


def test_a_map_fault_in_process_reads_as_in_the_child(tmp_path):
    path = hostile_file(tmp_path, "nan")
    child = _by_name(conformance.run_checks(f"{path}:Bad", load_scenario("slam_loop")))["landmarks"]
    here = _by_name(conformance.run_checks(f"{path}:Bad", load_scenario("slam_loop"),
                                           isolated=False))["landmarks"]
    assert child.message == here.message
    assert json.dumps(child.message)  # one line
    assert "\n" not in child.message
