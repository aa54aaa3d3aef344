"""``beacon-sim run``, ``eval`` and ``grade`` on a team scenario: exit
statuses, a row per robot and the team's, JSON fields, the joint PCRB in eval, and a team
filter that raises gets no score."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from student_filters import write_class

from beacon_sim.cli.main import main
from beacon_sim.core.metrics import anees_band
from beacon_sim.evaluation.grading import GradeConfig, grade, write_outputs
from beacon_sim.filters import team as team_filters

ROBOTS = ("scout", "relay", "explorer")


class Broken(team_filters.IndependentTeam):
    """A team filter that raises on its 20th update (1 s into a run)."""

    def __init__(self, ctx):
        super().__init__(ctx)
        self.n = 0

    def update(self, measurements):
        self.n += 1
        if self.n >= 20:
            raise ZeroDivisionError("broken team filter")
        super().update(measurements)


@pytest.fixture
def broken(monkeypatch):
    monkeypatch.setitem(team_filters.TEAM_FILTERS, "broken", Broken)


def test_run_prints_a_row_per_robot_and_the_team(capsys):
    assert main(["run", "team_sparse", "--duration", "3", "--seed", "4", "--filter", "independent",
                 "--filter", "centralised", "--filter", "ci"]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert "team_sparse" in lines[0] and "seed 4" in lines[0]
    for name in ("independent", "centralised", "ci"):
        assert any(line.startswith(name) for line in lines), name
    for robot in (*ROBOTS, "team"):
        rows = [line for line in lines if line[16:].startswith(robot)]
        assert len(rows) == 3, robot  # one per filter
    assert "ANEES 95 % band" in out


def test_run_json_fields(capsys):
    assert main(["run", "scenarios/team/team_sparse.toml", "--duration", "3", "--filter", "centralised",
                 "--filter", "independent:ukf", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["team"] is True and d["robots"] == list(ROBOTS) and d["steps"] == 60
    assert d["anees_band"] == pytest.approx(anees_band(1))
    assert d["team_anees_band"] == pytest.approx(anees_band(3))
    for name in ("centralised", "independent:ukf"):
        f = d["filters"][name]
        assert set(f["robots"]) == set(ROBOTS)
        for r in f["robots"].values():
            assert r["pos_rmse_m"] > 0 and r["anees_verdict"] in ("consistent", "optimistic", "pessimistic")
        assert f["team_pos_rmse_m"] > 0 and f["us_per_step"] > 0


@pytest.mark.parametrize("argv, says", [
    (["--filter", "nope"], "no team filter named 'nope'"),
    (["--filter", "independent:nope"], "unknown filter 'nope'"),
    (["--set", "ci.nope=1"], "unknown parameter 'nope'"),
    (["--set", "pf.n_particles=10"], "no team filter 'pf'"),
    (["--set", "centralised"], "expected NAME.KEY=VALUE"),
    (["--duration", "0.01"], "shorter than one tick"),
])
def test_run_and_eval_bad_input_is_one_line_and_status_2(argv, says, capsys):
    for cmd in (["run", "team_sparse"], ["eval", "team_sparse", "--runs", "1"]):
        assert main([*cmd, *argv]) == 2
        err = capsys.readouterr().err.strip()
        assert says in err and "\n" not in err, err


def test_run_a_team_filter_that_raises_gets_no_score(broken, capsys):
    assert main(["run", "team_sparse", "--duration", "3", "--filter", "broken", "--filter",
                 "independent", "--json"]) == 0
    cap = capsys.readouterr()
    d = json.loads(cap.out)
    b = d["filters"]["broken"]
    assert set(b) == {"failed"} and "ZeroDivisionError" in b["failed"]
    assert "team_pos_rmse_m" in d["filters"]["independent"]
    assert "filter broken failed" in cap.err


@pytest.fixture(scope="module")
def evaluated(tmp_path_factory):
    out = tmp_path_factory.mktemp("team_eval")
    argv = ["eval", "team_sparse", "--runs", "2", "--duration", "4", "--seed", "7", "--json",
            "--filter", "independent", "--filter", "centralised"]
    return argv, out


def test_eval_json_has_per_robot_and_team_figures_and_the_joint_bound(evaluated, capsys):
    argv, out = evaluated
    assert main([*argv, "--jobs", "1", "--out", str(out)]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["team"] is True and d["runs"] == 2 and d["seed"] == 7 and d["robots"] == list(ROBOTS)
    assert d["steps"] == 80 and len(d["run_checksums"]) == 2
    for robot in ROBOTS:
        b = d["pcrb"]["robots"][robot]
        assert 0 < b["pos_rmse_m"] <= b["alone_pos_rmse_m"] + 1e-12
    for name in ("independent", "centralised"):
        f = d["filters"][name]
        assert f["failed_runs"] == 0 and f["anees_band"] == pytest.approx(anees_band(2))
        assert f["team_anees_band"] == pytest.approx(anees_band(6))
        assert set(f["robots"]) == set(ROBOTS)
        for r in f["robots"].values():
            assert r["pos_rmse_m"] > 0 and r["anees"] > 0 and r["rmse_over_pcrb"] > 0
        assert f["team"]["pos_rmse_m"] > 0 and f["team"]["anees_verdict"] != "FAILED"
        assert [p["seed"] for p in f["per_run"]] == [7, 8]
    ind, cen = d["filters"]["independent"]["robots"], d["filters"]["centralised"]["robots"]
    assert cen["explorer"]["pos_rmse_m"] < ind["explorer"]["pos_rmse_m"]
    assert {p.name for p in out.iterdir()} >= {"eval.csv", "eval_runs.csv", "eval.json"}
    rows = (out / "eval.csv").read_text().splitlines()
    assert len(rows) == 1 + 2 * (len(ROBOTS) + 1)  # a row per filter and robot, and the team's
    assert json.loads((out / "eval.json").read_text())["filters"].keys() == d["filters"].keys()


def test_eval_on_two_processes_gives_the_same_figures(evaluated, capsys):
    argv, out = evaluated
    assert main([*argv, "--jobs", "2"]) == 0
    two = json.loads(capsys.readouterr().out)
    one = json.loads((out / "eval.json").read_text())
    assert two["run_checksums"] == one["run_checksums"]
    for name in one["filters"]:
        assert two["filters"][name]["robots"] == one["filters"][name]["robots"]


def test_eval_prints_a_table_per_robot(capsys):
    assert main(["eval", "team_sparse", "--runs", "1", "--duration", "2", "--jobs", "1",
                 "--filter", "ci"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("team_sparse (team of 3): 1 runs")
    assert [line[16:28].strip() for line in lines[2:6]] == [*ROBOTS, "team"]


def test_eval_a_team_filter_that_raises_gets_no_score(broken, capsys):
    argv = ["eval", "team_sparse", "--runs", "2", "--duration", "2", "--jobs", "1", "--json",
            "--filter", "broken", "--filter", "independent"]
    assert main(argv) == 0
    cap = capsys.readouterr()
    d = json.loads(cap.out)
    b = d["filters"]["broken"]
    assert b["failed_runs"] == 2 and b["team"]["pos_rmse_m"] is None
    assert b["team"]["anees_verdict"] == "FAILED"
    for r in b["robots"].values():
        assert r["pos_rmse_m"] is None and r["anees"] is None and r["anees_verdict"] == "FAILED"
    assert b["failures"][0]["time_s"] == pytest.approx(1.0)
    assert "ZeroDivisionError" in b["failures"][0]["reason"]
    assert d["filters"]["independent"]["team"]["pos_rmse_m"] > 0
    assert "broken failed in 2 run(s) of team_sparse (no score)" in cap.err
    assert main([*argv, "--strict"]) == 1


def test_eval_refuses_team_and_single_robot_scenarios_together(capsys):
    assert main(["eval", "team_sparse", "default", "--runs", "1"]) == 2
    assert "team scenarios and single-robot scenarios" in capsys.readouterr().err


def test_grade_a_students_filter_as_every_robots_own(tmp_path: Path):
    klass = write_class(tmp_path / "class", ["alice", "carol"])
    board = grade(klass, GradeConfig(scenarios=("team_sparse",), seeds=(0, 1), duration=4.0,
                                     time_limit=5.0), jobs=1)
    rows = {r["student"]: r for r in board.rows}
    ref = board.reference["team_sparse"]
    assert set(ref["robots"]) == set(ROBOTS) and ref["pos_rmse_m"] > 0
    alice = rows["alice"]  # the built-in EKF in a student's file: the reference exactly
    assert alice["rank"] == 1 and alice["failed_runs"] == 0
    t = alice["team"]["team_sparse"]
    assert set(t["robots"]) == set(ROBOTS)
    assert t["pos_rmse_m"] == pytest.approx(ref["pos_rmse_m"], rel=1e-12)
    assert t["over_reference"] == pytest.approx(1.0)
    assert alice["pos_rmse_m"] == pytest.approx(t["pos_rmse_m"])
    carol = rows["carol"]  # raises at 3 s: no score
    assert carol["failed_runs"] == 2 and carol["pos_rmse_m"] is None and carol["anees"] is None
    assert carol["failures"][0]["scenario"] == "team_sparse"
    assert "ZeroDivisionError" in carol["failures"][0]["reason"]
    written = write_outputs(board, tmp_path / "out")
    assert json.loads((tmp_path / "out" / "grade.json").read_text())["reference"]["team_sparse"]
    assert "independent EKF" in (tmp_path / "out" / "grade.html").read_text()
    assert len(written) == 3
