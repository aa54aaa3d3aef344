"""``beacon-sim grade``: a class of filter files, working, slow and
broken in every way; failed filters have no score and rank below working ones; the same
results on local processes and on a Dask LocalCluster; the page opens in chromium and sorts."""

from __future__ import annotations

import csv
import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest
from student_filters import STUDENTS, WORKING, write_class

from beacon_sim.cli.main import main
from beacon_sim.evaluation.grading import GradeConfig, grade, write_outputs

CONFIG = GradeConfig(scenarios=("default",), seeds=(0, 1), duration=6.0, time_limit=1.5)


@pytest.fixture(scope="module")
def klass(tmp_path_factory):
    return write_class(tmp_path_factory.mktemp("class"))


@pytest.fixture(scope="module")
def board(klass):
    return grade(klass, CONFIG, jobs=2)


def _rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def test_failed_filters_have_no_score_and_rank_below_working_ones(board, tmp_path):
    rows = board.rows
    assert {r["student"] for r in rows} == set(STUDENTS)
    working = [r["student"] for r in rows if not r["failed_runs"]]
    assert set(working) == set(WORKING)
    assert [r["student"] for r in rows[:len(WORKING)]] == working  # all working ones first
    for r in rows[len(WORKING):]:
        assert r["pos_rmse_m"] is None and r["anees"] is None and r["failures"], r["student"]
    why = {r["student"]: r["failures"][0]["reason"] for r in rows if r["failed_runs"]}
    assert "ZeroDivisionError" in why["carol"] and "NaN" in why["dave"]
    assert "time limit" in why["heidi"] and "does not import" in why["judy"]
    assert "memory" in why["mallory"].lower() and "not symmetric" in why["oscar"]
    write_outputs(board, tmp_path)
    csv_rows = _rows(tmp_path / "grade.csv")
    carol = next(r for r in csv_rows if r["student"] == "carol")
    assert carol["pos_rmse_m"] == "" and carol["status"] == "FAILED" and "3.00 s" in carol["failures"]
    assert int(carol["rank"]) > len(WORKING)
    html = (tmp_path / "grade.html").read_text()
    assert "<svg" in html and "<script>" in html and "http" not in html.replace(
        'xmlns="http://www.w3.org/2000/svg"', "")


def test_the_cli_writes_the_files(klass, tmp_path, capsys):
    cfg = tmp_path / "grade.toml"
    cfg.write_text('scenarios = ["default"]\nseeds = [3]\nduration = 3.0\ntime_limit = 1.0\n')
    code = main(["grade", str(klass), "--config", str(cfg), "--out", str(tmp_path / "o"),
                 "--jobs", "2", "--strict"])
    assert code == 1  # --strict: some filters failed
    out = capsys.readouterr().out
    assert "alice" in out and "FAILED" in out
    assert (tmp_path / "o" / "grade.html").exists() and (tmp_path / "o" / "grade.csv").exists()


def _without_cost(rows):
    return [{k: v for k, v in r.items() if k != "us_per_step"} for r in rows]


def test_local_cluster_gives_the_same_results_as_local_processes(board, klass, tmp_path):
    distributed = pytest.importorskip("dask.distributed", reason="the grade extra (Dask) is not installed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        remote = grade(klass, CONFIG, scheduler=client)
    write_outputs(board, tmp_path / "local")
    write_outputs(remote, tmp_path / "dask")
    assert _without_cost(_rows(tmp_path / "local" / "grade.csv")) == \
        _without_cost(_rows(tmp_path / "dask" / "grade.csv"))
    for a, b in zip(board.rows, remote.rows, strict=True):
        assert a["plot"] == b["plot"]


def _chromium() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser")


def test_the_page_opens_in_chromium_and_sorts(board, tmp_path):
    exe = _chromium()
    if exe is None:
        pytest.skip("Debian's chromium is not installed (.ci/run installs it with apt-get)")
    write_outputs(board, tmp_path)
    page = (tmp_path / "grade.html").resolve()
    flags = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
             "--no-first-run", f"--user-data-dir={tmp_path / 'profile'}"]
    shot = tmp_path / "grade.png"
    subprocess.run([*flags, f"--screenshot={shot}", "--window-size=1400,1200", page.as_uri()],
                   capture_output=True, timeout=120, check=False)
    assert shot.exists() and shot.stat().st_size > 10_000
    dom = subprocess.run([*flags, "--dump-dom", page.as_uri() + "#sort=student-desc"],
                         capture_output=True, text=True, timeout=120, check=False).stdout
    assert 'data-sorted="student-desc"' in dom  # the script ran and sorted
    order = re.findall(r'<tr class="(ok|failed)"[^>]*data-student="([^"]+)"', dom)
    names = [n for _, n in order]
    kinds = [k for k, _ in order]
    assert kinds == sorted(kinds, key=lambda k: k == "failed")  # failed never above working
    ok = [n for k, n in order if k == "ok"]
    assert ok == sorted(ok, reverse=True) and len(names) == len(STUDENTS)


@pytest.mark.parametrize("text, says", [
    ("seeds = 2", "seeds = 2: expected a list of 1 to 10000 integer seeds"),
    ("seeds = [-1]", "seeds = [-1]: expected a list"),
    ("seeds = [1.5]", "seeds = [1.5]: expected a list"),
    ("seeds = []", "seeds = []: expected a list"),
    ("scenarios = 'default'", "scenarios = 'default': expected a list of 1 to 10000 names"),
    ("duration = inf", "duration = inf: expected a number in [0, 86400]"),
    ("duration = -3", "duration = -3: expected a number"),
    ("time_limit = 0", "time_limit = 0: expected a number in (0, 86400]"),
    ("time_limit = nan", "time_limit = nan: expected a number"),
    ("memory_limit_gb = 'x'", "memory_limit_gb = 'x': expected a number in [0, 10000]"),
    ("class_name = 'a b'", "class_name = 'a b': expected a Python class name"),
])
def test_a_bad_grading_configuration_names_the_key_and_what_was_expected(tmp_path, text, says):
    from beacon_sim.evaluation.grading import GradeError, load_config

    cfg = tmp_path / "grade.toml"
    cfg.write_text(text + "\n")
    with pytest.raises(GradeError) as err:
        load_config(cfg)
    assert str(err.value) == f"{cfg}: {says}" or str(err.value).startswith(f"{cfg}: {says}")


def test_a_good_grading_configuration_is_read(tmp_path):
    from beacon_sim.evaluation.grading import load_config

    cfg = tmp_path / "grade.toml"
    cfg.write_text('scenarios = ["default", "team_sparse"]\nseeds = [3, 4]\nduration = 0\n'
                   'time_limit = 5\nmemory_limit_gb = 0\n')
    c = load_config(cfg)
    assert (c.scenarios, c.seeds, c.duration, c.time_limit, c.memory_limit_gb) == \
        (("default", "team_sparse"), (3, 4), None, 5.0, 0.0)


BLIND = '''
import math
import numpy as np
from beacon_sim.filters.base import FilterBase, GaussianBelief


class Blind(FilterBase):
    """Dead reckoning written by a student: ignores every reading."""

    def reset(self, initial):
        self.m = np.array(initial.mean, float)
        self.P = np.array(initial.cov, float)

    def predict(self, control, dt):
        th = self.m[2]
        self.m = self.m + np.array([control.v * dt * math.cos(th), control.v * dt * math.sin(th),
                                    control.omega * dt])
        self.m[2] = (self.m[2] + math.pi) % (2 * math.pi) - math.pi
        self.P = self.P + np.diag([0.02, 0.02, 0.01]) * dt

    def update(self, measurements):
        pass

    def estimate(self):
        return self.m.copy(), self.P.copy()
'''


def test_no_row_says_a_bare_consistent_beside_an_error_over_twice_the_bound(tmp_path):
    """The page's and the CSV's verdict weigh the error against the bound."""
    klass = tmp_path / "class"
    klass.mkdir()
    (klass / "blind.py").write_text(BLIND)
    shutil.copy(Path(__file__).parents[1] / "attacks" / "honest.py", klass / "honest.py")
    board = grade(klass, GradeConfig(scenarios=("default",), seeds=(0,), duration=40.0), jobs=2)
    far = [r for r in board.rows if r["rmse_over_pcrb"] is not None and r["rmse_over_pcrb"] > 2]
    assert [r["student"] for r in far] == ["blind"]  # the honest EKF is near the bound
    for r in board.rows:
        if r in far:
            assert ", but " in r["verdict"] and "x the bound" in r["verdict"], r["verdict"]
        else:
            assert r["verdict"] == r["anees_verdict"] or "x the bound" in r["verdict"]
    write_outputs(board, tmp_path / "out")
    row = next(r for r in _rows(tmp_path / "out" / "grade.csv") if r["student"] == "blind")
    assert ", but " in row["verdict"]
    assert far[0]["verdict"] in (tmp_path / "out" / "grade.html").read_text()


def test_outputs_name_a_scenario_file_not_its_folder(tmp_path, capsys):
    """The files grade.json, grade.csv and the pages name a scenario given by path by its file
    name (a shipped one by its name), never by the folder it is in, since they are shared;
    the runs still load it from there, a team scenario's in the workers too."""
    klass = write_class(tmp_path / "class", ["alice", "carol"])
    where = tmp_path / "where" / "they" / "are"
    where.mkdir(parents=True)
    shipped = Path(__file__).resolve().parents[2] / "scenarios"
    shutil.copy(shipped / "default.toml", where / "mine.toml")
    shutil.copy(shipped / "team" / "team_sparse.toml", where / "team.toml")
    cfg = tmp_path / "grade.toml"
    cfg.write_text(f'scenarios = ["{where / "mine.toml"}", "{where / "team.toml"}", "default"]\n'
                   'seeds = [3]\nduration = 3.0\ntime_limit = 2.0\n')
    out = tmp_path / "o"
    assert main(["grade", str(klass), "--config", str(cfg), "--out", str(out), "--jobs", "2"]) == 0
    assert str(where) not in capsys.readouterr().out
    board = json.loads((out / "grade.json").read_text(encoding="utf-8"))
    names = ["mine.toml", "team.toml", "default"]
    assert board["config"]["scenarios"] == names and list(board["reference"]) == ["team.toml"]
    alice = next(r for r in board["rows"] if r["student"] == "alice")
    assert not alice["failed_runs"] and [d["scenario"] for d in alice["run_detail"]] == names
    assert list(alice["team"]) == ["team.toml"]
    carol = next(r for r in board["rows"] if r["student"] == "carol")
    assert {f["scenario"] for f in carol["failures"]} <= set(names)
    shared = [f for f in out.rglob("*") if f.suffix in (".json", ".csv", ".html")]
    assert len(shared) >= 5
    for f in shared:
        assert str(where) not in f.read_text(encoding="utf-8"), f.name
