"""A failed filter gets no score: ``run --json``, ``eval`` (table, JSON, CSV)
show FAILED with the reason and the time, no accuracy figures; ``--strict`` exits 1."""

from __future__ import annotations

import csv
import json

import pytest
from student_filters import write_class

from beacon_sim.cli.main import main


@pytest.fixture(scope="module")
def klass(tmp_path_factory):
    return write_class(tmp_path_factory.mktemp("class"), ["alice", "carol", "dave", "erin", "oscar"])


def test_run_json_has_no_rmse_for_a_crashed_filter(klass, capsys):
    code = main(["run", "default", "--filter", "ekf", "--filter", f"{klass}/carol.py:MyEkf",
                 "--duration", "5", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0
    crashed = out["filters"]["MyEkf"]
    assert "ZeroDivisionError" in crashed["failed"]
    assert crashed["failed_time_s"] == pytest.approx(3.0)
    assert crashed["pos_rmse_m"] is None and crashed["anees"] is None
    assert out["filters"]["ekf"]["pos_rmse_m"] > 0


def test_run_table_says_failed_with_the_time(klass, capsys):
    assert main(["run", "default", "--filter", f"{klass}/dave.py:MyEkf", "--duration", "3"]) == 0
    out = capsys.readouterr().out
    assert "FAILED at 2.00 s: estimate() returned NaN or infinity" in out


@pytest.mark.parametrize("stem,reason", [("carol", "ZeroDivisionError"), ("dave", "NaN"),
                                         ("erin", "positive semi-definite"),
                                         ("oscar", "not symmetric")])
def test_eval_gives_a_crashed_filter_no_score(klass, tmp_path, capsys, stem, reason):
    out_dir = tmp_path / "out"
    args = ["eval", "default", "--filter", "ekf", "--filter", f"{klass}/{stem}.py:MyEkf",
            "--runs", "2", "--duration", "4", "--jobs", "1", "--json", "--out", str(out_dir)]
    assert main(args) == 0
    doc = json.loads(capsys.readouterr().out)
    bad, good = doc["filters"]["MyEkf"], doc["filters"]["ekf"]
    assert bad["failed_runs"] == 2 and reason in bad["failures"][0]["reason"]
    assert bad["failures"][0]["time_s"] is not None
    for key in ("pos_rmse_m", "anees", "rmse_over_pcrb", "heading_rmse_rad"):
        assert bad[key] is None, key
    assert bad["anees_verdict"] == "FAILED"
    assert all(p["pos_rmse_m"] is None for p in bad["per_run"])
    assert good["failed_runs"] == 0 and good["pos_rmse_m"] > 0
    with open(out_dir / "eval.csv", newline="") as fh:
        rows = {r["filter"]: r for r in csv.DictReader(fh)}
    assert rows["MyEkf"]["pos_rmse_m"] == "" and rows["MyEkf"]["anees"] == ""
    assert rows["MyEkf"]["failed_runs"] == "2" and reason in rows["MyEkf"]["first_failure"]
    assert float(rows["ekf"]["pos_rmse_m"]) > 0
    assert main([*args, "--strict"]) == 1
    table = capsys.readouterr()
    assert "failed in 2 run(s)" in table.err


def test_eval_table_says_failed_in_k_of_n_runs(klass, capsys):
    assert main(["eval", "default", "--filter", f"{klass}/carol.py:MyEkf", "--runs", "2",
                 "--duration", "4", "--jobs", "1"]) == 0
    out = capsys.readouterr().out
    assert "FAILED in 2/2 runs (no score); first: seed 0 at 3.00 s: ZeroDivisionError" in out


def test_eval_stops_an_endless_loop_and_goes_on(tmp_path, capsys):
    import time

    klass = write_class(tmp_path / "loop", ["heidi"])
    t0 = time.perf_counter()
    code = main(["eval", "default", "--filter", "ekf", "--filter", f"{klass}/heidi.py:MyEkf",
                 "--runs", "2", "--duration", "4", "--jobs", "2", "--json", "--time-limit", "1"])
    elapsed = time.perf_counter() - t0
    doc = json.loads(capsys.readouterr().out)
    assert code == 0 and elapsed < 30
    bad = doc["filters"]["MyEkf"]
    assert bad["failed_runs"] == 2 and "time limit" in bad["failures"][0]["reason"]
    assert bad["pos_rmse_m"] is None and doc["filters"]["ekf"]["pos_rmse_m"] > 0


BROKEN_LIFE = '''
from beacon_sim.filters.gaussian.dead_reckoning import DeadReckoning


class BadInit(DeadReckoning):
    def __init__(self, ctx):
        raise RuntimeError("my init is broken")


class Exits(DeadReckoning):
    def predict(self, control, dt):
        raise SystemExit(3)
'''


@pytest.mark.parametrize("cls,reason", [("BadInit", "construction failed: RuntimeError: my init is broken"),
                                        ("Exits", "SystemExit(3) raised by the filter")])
def test_eval_fails_only_the_filter_whose_init_raises_or_that_exits(tmp_path, capsys, cls, reason):
    """A student's __init__ that raises, or sys.exit() in predict, fails that filter in every
    run (in the worker processes too); the EKF beside it is scored; --strict exits 1."""
    path = tmp_path / "broken.py"
    path.write_text(BROKEN_LIFE)
    code = main(["eval", "default", "--filter", f"{path}:{cls}", "--filter", "ekf", "--runs", "2",
                 "--duration", "3", "--jobs", "2", "--json", "--strict"])
    out = json.loads(capsys.readouterr().out)
    assert code == 1
    bad = out["filters"][cls]
    assert bad["pos_rmse_m"] is None and bad["failed_runs"] == 2
    assert all(reason in f for f in bad["failed"])
    assert out["filters"]["ekf"]["pos_rmse_m"] > 0


def _worker_address_limit() -> int:
    import resource

    return resource.getrlimit(resource.RLIMIT_AS)[0]


def test_eval_workers_have_a_memory_limit():
    """A filter that hoards memory in an eval worker meets MemoryError (its run fails, the
    sweep goes on) instead of the out-of-memory killer: the workers start with a limit."""
    from concurrent.futures import ProcessPoolExecutor

    from beacon_sim.evaluation.montecarlo import WORKER_MEMORY_GB, init_worker

    with ProcessPoolExecutor(max_workers=1, initializer=init_worker) as pool:
        limit = pool.submit(_worker_address_limit).result()
    assert 0 < limit <= WORKER_MEMORY_GB * 2**30
