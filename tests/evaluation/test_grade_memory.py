"""A student's memory limit is each run's own: an honest filter that keeps a big table gets
the verdict and the figures of the same filter without the table, with 1, 3 or 5 seeds (the
seeds and the probes fed together share one process; when they run out of memory together
they are fed again one per process), and a filter over the limit on its own fails with
every count. Nothing of one batch's memory (its filters, the copies of the file they came
from) is left for the next batch in the same process.

The scale: a child holds about 190 MB of address space before any filter; the limit here is
0.5 GB and the table 150 MB, so one filter with its table fits, four together do not.
"""

from __future__ import annotations

import pytest

from beacon_sim.core.scenario import load_scenario
from beacon_sim.evaluation.grading import GradeConfig, grade
from beacon_sim.evaluation.montecarlo import isolated_run, simulate_run
from beacon_sim.hosting.containment import Limits
from beacon_sim.hosting.isolated import FilterChild

MEMORY_GB = 0.5
TABLE_MB = 150

PLAIN = """
from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter


class Plain(ExtendedKalmanFilter):
    pass
"""
#: The plain EKF keeping a table it never reads: the same estimates, more memory.
TABLE = f"""
import numpy as np
from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter


class Table(ExtendedKalmanFilter):
    def __init__(self, ctx):
        super().__init__(ctx)
        self.table = np.ones({TABLE_MB} * 2**20 // 8)
"""
#: Over the limit even alone.
HOG = """
import numpy as np
from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter


class Hog(ExtendedKalmanFilter):
    def __init__(self, ctx):
        super().__init__(ctx)
        self.table = np.ones(600 * 2**20 // 8)
"""
FIGURES = ("pos_rmse_m", "heading_rmse_rad", "anees", "anees_verdict", "failed_runs", "deterministic",
           "readings_used")


@pytest.fixture(scope="module")
def boards(tmp_path_factory):
    klass = tmp_path_factory.mktemp("memory_class")
    for name, text in (("plain", PLAIN), ("table", TABLE), ("hog", HOG)):
        (klass / f"{name}.py").write_text(text)
    out = {}
    for n in (1, 3, 5):
        cfg = GradeConfig(scenarios=("two_rooms",), seeds=tuple(range(n)), duration=3.0, time_limit=20.0,
                          memory_limit_gb=MEMORY_GB, allow_unisolated=True)
        out[n] = {r["student"]: r for r in grade(klass, cfg, jobs=1, secret=b"\x05" * 32).rows}
    return out


@pytest.mark.parametrize("seeds", [1, 3, 5])
def test_an_honest_table_gets_the_plain_filters_verdict_with_any_number_of_seeds(boards, seeds):
    rows = boards[seeds]
    table, plain = rows["table"], rows["plain"]
    assert table["failed_runs"] == 0, table["failures"]
    assert not table.get("probe_failures"), "the probes were starved of memory by the scored seeds"
    assert {k: table.get(k) for k in FIGURES} == {k: plain.get(k) for k in FIGURES}
    assert table["deterministic"] is True and table["readings_used"] is True


@pytest.mark.parametrize("seeds", [1, 3, 5])
def test_a_filter_over_the_limit_alone_fails_every_run_with_any_number_of_seeds(boards, seeds):
    hog = boards[seeds]["hog"]
    assert hog["failed_runs"] == seeds
    assert all("MemoryError" in f["reason"] for f in hog["failures"]), hog["failures"]


MODULE_TABLE = """
import numpy as np
from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter

TABLE = np.ones(120 * 2**20 // 8)  # at module level: each copy of the file holds one


class ModuleTable(ExtendedKalmanFilter):
    def estimate(self):  # a method: the class holds its module's globals, the table with them
        return super().estimate()
"""


def test_a_batch_leaves_nothing_of_its_memory_to_the_next_in_the_same_process(tmp_path):
    """Three runs one after the other in one child: each batch imports the file afresh, so
    the previous batch's filter and copy (and the copy the load made) must be gone first."""
    src = tmp_path / "module_table.py"
    src.write_text(MODULE_TABLE)
    sims = [simulate_run(load_scenario("two_rooms"), seed, 2.0, index=seed) for seed in range(3)]
    with FilterChild(src, None, tmp_path / "log.txt", "process", Limits(memory_gb=MEMORY_GB)) as child:
        for sr in sims:
            run, rep = isolated_run(child, sr, 20.0)
            fr = next(iter(run.filters.values()))
            assert fr.failed is None, fr.failed
            assert not rep.get("failed_child")
