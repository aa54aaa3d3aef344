"""`grade` with a scan-based filter (a range finder in a map world): the
`new-filter --scan` template graded beside the built-in mcl, its figures those of the
in-process run of the same seeds, and a child that gets the grid it is entitled to and
never the truth."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from beacon_sim.core.scenario import load_scenario
from beacon_sim.evaluation.grading import GradeConfig, grade, is_scan_scenario
from beacon_sim.evaluation.montecarlo import one_run, simulate_run
from beacon_sim.evaluation.summary import Thresholds, evaluate
from beacon_sim.hosting.client import hosted_context
from beacon_sim.templates import render_scan_template

#: Short runs; a CPU-time limit far above the template's (about 0.6 ms a step here).
CONFIG = GradeConfig(scenarios=("office",), seeds=(0, 1), duration=6.0, time_limit=30.0)

PEEK = '''

class Sam(Honest):
    """Looks for the truth in its own process on the 10th tick, and takes it if found
    (named as the honest file's class: the same random stream, so the same figures when it
    finds nothing)."""

    def reset(self, initial):
        super().reset(initial)
        self.ticks, self.found = 0, None
        grid = self.ctx.world.grid
        print("grid", None if grid is None else tuple(grid.shape), flush=True)

    def predict(self, control, dt):
        super().predict(control, dt)

    def update(self, measurements):
        super().update(measurements)
        self.ticks += 1
        if self.ticks == 10:
            import gc
            names = {"Simulation", "Step", "SimulatedRun", "RunOutput", "TeamSimulation"}
            found = [o for o in gc.get_objects()
                     if type(o).__name__ in names or hasattr(type(o), "true_pose")]
            print("found", len(found), flush=True)
            self.found = found[0] if found else None

    def estimate(self):
        if self.found is not None:
            return np.array(self.found.true_pose, dtype=float), np.eye(3) * 1e-6
        return super().estimate()
'''


@pytest.fixture
def scan_class(tmp_path):
    folder = tmp_path / "class"
    folder.mkdir()
    (folder / "sam.py").write_text(render_scan_template("Sam", "sam.py"), encoding="utf-8")
    return folder


def test_office_and_corridor_are_scan_scenarios():
    assert is_scan_scenario(load_scenario("office")) and is_scan_scenario(load_scenario("corridor"))
    assert not is_scan_scenario(load_scenario("default"))


def test_grade_scores_the_scan_template_as_its_in_process_run_beside_mcl(scan_class, tmp_path):
    from beacon_sim.evaluation.grading import write_outputs

    board = grade(scan_class, CONFIG, jobs=1)
    row = board.rows[0]
    assert row["student"] == "sam" and not row["failures"], row["failures"]
    ref = board.scan_reference["office"]
    assert ref["filter"] == "mcl" and 0 < ref["pos_rmse_m"] < 0.5
    # the same seeds in process, the filter named as the grader names it (its class)
    sc = load_scenario("office")
    # (with the grade's secret: the template draws from ctx.rng, which grade keys with it)
    runs = [one_run(sc, [f"{scan_class / 'sam.py'}:Sam"], {}, seed, CONFIG.duration, index=i,
                    secret=bytes.fromhex(board.secret)) for i, seed in enumerate(CONFIG.seeds)]
    for detail, run in zip(row["run_detail"], runs, strict=True):
        e = run.filters["Sam"].err
        assert detail["pos_rmse_m"] == float(np.sqrt(np.mean(e[:, 0] ** 2 + e[:, 1] ** 2)))
    alone = evaluate(sc, runs, Thresholds())[0]["filters"]["Sam"]
    assert row["pos_rmse_m"] == alone["pos_rmse_m"] and row["anees"] == alone["anees"]
    # the scan's PCRB (core/scan_jacobian.py) gives the row a bound: RMSE/PCRB is a number
    assert row["rmse_over_pcrb"] == alone["rmse_over_pcrb"]
    assert row["rmse_over_pcrb"] is not None and np.isfinite(row["rmse_over_pcrb"])
    assert row["rmse_over_pcrb"] > 1.0
    assert row["scan"]["office"]["pos_rmse_m"] == alone["pos_rmse_m"]
    assert row["scan"]["office"]["reference_pos_rmse_m"] == ref["pos_rmse_m"]
    # mcl's reference is eval's figure for mcl on the same seeds
    mcl = [one_run(sc, ["mcl"], {}, seed, CONFIG.duration, index=i) for i, seed in enumerate(CONFIG.seeds)]
    assert ref["pos_rmse_m"] == evaluate(sc, mcl, Thresholds())[0]["filters"]["mcl"]["pos_rmse_m"]
    write_outputs(board, tmp_path / "out")
    assert "the built-in mcl on the same seeds" in (tmp_path / "out" / "grade.html").read_text()


def test_the_child_gets_the_grid_and_never_the_truth(scan_class):
    """What the grader sends a scan filter: the context (with the occupancy grid it is
    entitled to) and each tick's control and scan. No true pose after the start is in any of
    those bytes; a filter that looks for the truth in its process finds nothing and scores
    exactly as the honest template."""
    sc = load_scenario("office")
    sr = simulate_run(sc, 0, 3.0, 0)
    ctx = hosted_context(sr.scenario, sr.stream_key, "Sam", None)
    assert ctx.world.grid is not None and np.array_equal(ctx.world.grid.occupied, sc.world.grid.occupied)
    sent = pickle.dumps(ctx) + b"".join(sr.frames)
    for pose in sr.truth[1:]:
        assert pose.tobytes() not in sent and pose[:2].tobytes() not in sent
    for frame in sr.frames[:50]:
        op, control, dt, meas, _want_prior = pickle.loads(frame[4:])
        assert op == "step" and set(vars(control)) == {"v", "omega"} and isinstance(dt, float)
        assert all(m.kind == "range_finder" and not hasattr(m, "true_pose") for m in meas)

    peek = scan_class / "peek.py"
    peek.write_text(render_scan_template("Honest", "peek.py") + PEEK, encoding="utf-8")
    board = grade(scan_class, CONFIG, jobs=1)
    rows = {r["student"]: r for r in board.rows}
    assert not rows["peek"]["failures"], rows["peek"]["failures"]
    assert rows["peek"]["pos_rmse_m"] == rows["sam"]["pos_rmse_m"]  # found nothing to use
    log = board.logs["peek"]
    assert f"grid {tuple(sc.world.grid.shape)}" in log
    assert "found 0" in log and "found 1" not in log


def test_a_scans_unknown_information_gives_a_nan_bound_not_an_error():
    """The PCRB of a range finder is not computed (NaN information): the runs with it get a
    NaN bound, the others the same bound as alone (LAPACK's eigh raises on NaN)."""
    from beacon_sim.evaluation.pcrb import information_update

    P = np.stack([np.eye(3) * 0.5, np.eye(3) * 2.0])
    info = np.stack([np.full((3, 3), np.nan), np.diag([1.0, 4.0, 0.0])])
    out = information_update(P, info)
    assert np.all(np.isnan(out[0]))
    assert np.array_equal(out[1], information_update(P[1:], info[1:])[0])
    assert np.allclose(out[1], np.diag([2.0 / 3.0, 2.0 / 9.0, 2.0]))
