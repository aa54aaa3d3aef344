"""One verdict rule in a grade: the consistency word beside a row's ANEES is the word for
that number (never "consistent/optimistic" beside ANEES 30,884), each scenario's ANEES and
word are shown when they differ, and a filter without a finite ANEES is never "ok"."""

from __future__ import annotations

import math
import textwrap

import pytest

from beacon_sim.core.metrics import anees_band
from beacon_sim.evaluation.grading import GradeConfig, grade, status
from beacon_sim.evaluation.grading.scoring import rank_key, row_anees_verdict
from beacon_sim.runs.headless import anees_verdict

#: An EKF honest on a small room and claiming a covariance 1e-4 of its own on a wide one:
#: consistent on two_rooms (10 m wide), wildly optimistic on default (12 m wide).
SPLIT = textwrap.dedent("""
    from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter


    class Split(ExtendedKalmanFilter):
        def estimate(self):
            mean, cov = super().estimate()
            wide = self.ctx.world.bounds[2] - self.ctx.world.bounds[0] > 11.0
            return mean, (1e-4 * cov if wide else cov)
""")


def test_the_rows_word_is_the_word_for_its_number():
    word, flag = row_anees_verdict(30884.0, ["consistent", "optimistic"], [3.1, 61765.0],
                                   ["two_rooms", "default"], 5)
    assert word == "optimistic" and "/" not in word
    assert flag is not None and "default 61,765.00 (optimistic)" in flag and "two_rooms 3.10" in flag
    lo, hi = anees_band(10)
    assert row_anees_verdict(3.0, ["consistent", "consistent"], [2.9, 3.1], ["a", "b"], 5) == \
        (anees_verdict(3.0, lo, hi), None)
    inf = row_anees_verdict(math.inf, ["consistent", "optimistic"], [3.0, math.inf], ["a", "b"], 5)
    assert inf[0] == "FAILED"
    assert row_anees_verdict(7.0, ["optimistic"], [7.0], ["a"], 5) == ("optimistic", None)


def test_a_row_without_a_finite_anees_is_never_ok_nor_above_a_consistent_one():
    ok = {"student": "a", "failed_runs": 0, "pos_rmse_m": 0.5, "suspicious": None}
    nan = {"student": "b", "failed_runs": 1, "pos_rmse_m": None, "suspicious": None}
    assert status(nan) == "FAILED" and rank_key(ok) < rank_key(nan)


def test_a_grade_over_two_scenarios_says_the_word_for_its_mean(tmp_path):
    folder = tmp_path / "class"
    folder.mkdir()
    (folder / "split.py").write_text(SPLIT, encoding="utf-8")
    board = grade(folder, GradeConfig(scenarios=("two_rooms", "default"), seeds=(0, 1), duration=8.0,
                                      time_limit=10.0), jobs=1, secret=bytes(32))
    row = board.rows[0]
    assert not row["failed_runs"], row["failures"]
    assert row["anees"] > 100 and row["anees_verdict"] == "optimistic"
    assert "/" not in row["verdict"] and row["verdict"].startswith("optimistic")
    flag = next(f for f in row["flags"] if f.startswith("ANEES by scenario"))
    assert "two_rooms" in flag and "(consistent)" in flag and "default" in flag and "(optimistic)" in flag


@pytest.mark.parametrize("words", [["consistent"], ["consistent", "consistent"]])
def test_one_word_needs_no_flag(words):
    assert row_anees_verdict(3.0, words, [3.0] * len(words), ["a", "b"][:len(words)], 20)[1] is None

