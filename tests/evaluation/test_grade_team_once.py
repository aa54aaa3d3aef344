"""A team scenario in `grade` is simulated once per (scenario, seed) and each
robot's ticks are streamed to every student's child (one copy of the filter per robot and
seed, fed together), as the single-robot runs are; the figures are those of the same
filter's in-process team run bit for bit."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from beacon_sim.core.scenario import load_team_scenario
from beacon_sim.evaluation.grading import GradeConfig, grade, simulate_team_run
from beacon_sim.runs.headless import run_headless

ATTACKS = Path(__file__).parents[1] / "attacks"

BREAKS = '''
from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter


class Breaks(ExtendedKalmanFilter):
    """An EKF that raises on its 60th step (on every robot)."""

    def reset(self, initial):
        super().reset(initial)
        self.n = 0

    def update(self, measurements):
        self.n += 1
        if self.n == 60:
            raise ValueError("my update broke")
        super().update(measurements)
'''

#: What a row's figures are (its cost, measured in another process each time, is not).
FIGURES = ("pos_rmse_m", "heading_rmse_rad", "anees", "anees_verdict", "verdict", "rmse_over_pcrb",
           "failed_runs", "team", "plot")


def test_the_team_simulated_once_is_the_headless_runs_truth():
    team = load_team_scenario("team_sparse")
    ts = simulate_team_run(team, 4, 6.0)
    res = run_headless(team, ["independent:ekf"], seed=4, duration=6.0)
    assert ts.truth_checksum == res.truth_checksum
    assert (ts.truth[1:] == res.true_poses).all() and (ts.truth[0] == res.initial_poses).all()
    assert (ts.controls == res.controls).all()
    assert len(ts.robots) == team.n_robots and all(len(r.frames) == 120 for r in ts.robots)


def test_team_runs_streamed_once_equal_the_in_process_team_run_bit_for_bit(tmp_path):
    """The built-in EKF as a student's file (honest.py), its robots' copies fed in the
    student's child, scores what the in-process team run of the built-in EKF (the grade's
    team reference) scores, bit for bit; the functions form of the same EKF too."""
    klass = tmp_path / "class"
    klass.mkdir()
    shutil.copy(ATTACKS / "honest.py", klass / "honest.py")
    shutil.copy(ATTACKS / "functions.py", klass / "functions.py")
    (klass / "breaks.py").write_text(BREAKS, encoding="utf-8")
    cfg = GradeConfig(scenarios=("team_sparse",), seeds=(0, 1), duration=6.0, time_limit=30.0)
    board = grade(klass, cfg, jobs=2)
    rows = {r["student"]: r for r in board.rows}
    reference = board.reference["team_sparse"]
    assert set(rows) == {"honest", "functions", "breaks"}
    for name in ("honest", "functions"):
        assert not rows[name]["failures"], rows[name]["failures"]
        for key in ("pos_rmse_m", "heading_rmse_rad", "anees", "anees_verdict"):
            assert rows[name][key] == reference[key], (name, key)
        assert rows[name]["rmse_over_pcrb"] == reference["rmse_over_pcrb"], name
    r = rows["breaks"]  # a copy that breaks: the whole team's run, no score
    assert r["failed_runs"] == 2 and r["pos_rmse_m"] is None
    assert all("ValueError: my update broke" in f["reason"] for f in r["failures"]), r["failures"]


def test_team_runs_streamed_once_on_dask_equal_local_processes(tmp_path):
    """The team runs go to every Dask worker once (scattered with the single-robot runs)."""
    distributed = pytest.importorskip("dask.distributed", reason="the grade extra (Dask) is not installed")
    klass = tmp_path / "class"
    klass.mkdir()
    shutil.copy(ATTACKS / "honest.py", klass / "honest.py")
    cfg = GradeConfig(scenarios=("default", "team_sparse"), seeds=(0,), duration=4.0)
    local = grade(klass, cfg, jobs=1).rows[0]
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        remote = grade(klass, cfg, scheduler=client).rows[0]
    assert not local["failures"] and not remote["failures"]
    for key in FIGURES:
        assert local.get(key) == remote.get(key), key
