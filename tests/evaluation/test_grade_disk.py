"""What a student's process may write is capped (``disk_limit_mb``): under bubblewrap by the
sizes of its RAM file systems (a write over it fails), at the process level by measuring
what it wrote after each batch of runs; either way its runs fail, the page names the limit,
and an honest classmate is untouched."""

from __future__ import annotations

import pytest

from beacon_sim.evaluation.grading import GradeConfig, grade
from beacon_sim.hosting.containment import bwrap_problem

HONEST = """
from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter


class Honest(ExtendedKalmanFilter):
    pass
"""
#: Three files of 6 MB each in its working folder (each under the 8 MB a file may have).
WRITER = """
import os
from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter


class Writer(ExtendedKalmanFilter):
    def __init__(self, ctx):
        super().__init__(ctx)
        for k in range(3):
            with open(f"blob{k}-{id(self)}.bin", "wb") as fh:
                fh.write(os.urandom(6 * 2**20))
"""


@pytest.mark.parametrize("sandbox", ["process", "bwrap"])
def test_what_a_student_writes_is_capped_and_the_page_says_so(tmp_path, sandbox):
    if sandbox == "bwrap" and bwrap_problem():
        pytest.skip(f"no bubblewrap sandbox here: {bwrap_problem()}")
    folder = tmp_path / "class"
    folder.mkdir()
    (folder / "honest.py").write_text(HONEST)
    (folder / "writer.py").write_text(WRITER)
    cfg = GradeConfig(scenarios=("two_rooms",), seeds=(0, 1), duration=2.0, time_limit=20.0, sandbox=sandbox,
                      allow_unisolated=True, disk_limit_mb=12.0)
    rows = {r["student"]: r for r in grade(folder, cfg, jobs=1, secret=bytes(32)).rows}
    assert rows["honest"]["failed_runs"] == 0, rows["honest"]["failures"]
    w = rows["writer"]
    assert w["failed_runs"] == 2, w["failures"]
    words = "No space left on device" if sandbox == "bwrap" else "disk limit: the filter's process wrote"
    assert all(words in f["reason"] for f in w["failures"]), w["failures"]
    assert any(f.startswith("limit hit: disk") for f in w["flags"]), w["flags"]
    # the same file under a roomier limit writes what it likes
    roomy = {r["student"]: r for r in grade(folder, GradeConfig(**{**cfg.__dict__, "disk_limit_mb": 200.0}),
                                            jobs=1, secret=bytes(32)).rows}
    assert roomy["writer"]["failed_runs"] == 0, roomy["writer"]["failures"]
