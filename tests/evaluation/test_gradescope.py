"""A grade a course platform takes: the example rubric (examples/gradescope/grade.toml) scored
from each student's runs, written as Gradescope's results.json (validated against the
fields Gradescope documents), the same points on the page and in the CSV, and the
``autograde`` entry a course's run_autograder calls on one submission."""

from __future__ import annotations

import csv
import dataclasses
import json
from pathlib import Path

import jsonschema
import numpy as np
import pytest
from student_filters import write_class

from beacon_sim.cli.main import main
from beacon_sim.evaluation.grading import GradeError, grade, load_config, write_outputs
from beacon_sim.evaluation.grading.gradescope import results_json, write_gradescope
from beacon_sim.evaluation.grading.rubric import RubricItem, parse_rubric, score_row, tracking_figures

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "gradescope" / "grade.toml"

#: Gradescope's documented results.json ("Autograder Specifications", Output format): the
#: top-level fields and each test's; nothing else is allowed, so a stray field fails.
VISIBILITY = {"enum": ["hidden", "after_due_date", "after_published", "visible"]}
SCHEMA = {
    "type": "object",
    "additionalProperties": False,
    "properties": {
        "score": {"type": "number"},
        "execution_time": {"type": "number", "minimum": 0},
        "output": {"type": "string"},
        "output_format": {"enum": ["text", "html", "simple_format", "md", "ansi"]},
        "test_output_format": {"enum": ["text", "html", "simple_format", "md", "ansi"]},
        "test_name_format": {"enum": ["text", "html", "simple_format", "md", "ansi"]},
        "visibility": VISIBILITY,
        "stdout_visibility": VISIBILITY,
        "extra_data": {"type": "object"},
        "leaderboard": {"type": "array"},
        "tests": {"type": "array", "items": {
            "type": "object",
            "additionalProperties": False,
            "required": ["score", "max_score", "name"],
            "properties": {
                "score": {"type": "number"},
                "max_score": {"type": "number"},
                "status": {"enum": ["passed", "failed"]},
                "name": {"type": "string"},
                "name_format": {"enum": ["text", "html", "simple_format", "md", "ansi"]},
                "number": {"type": "string"},
                "output": {"type": "string"},
                "output_format": {"enum": ["text", "html", "simple_format", "md", "ansi"]},
                "tags": {"type": "array", "items": {"type": "string"}},
                "visibility": VISIBILITY,
                "extra_data": {"type": "object"},
            }}},
    },
}


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    """alice (the EKF), bob (covariance 4x: pessimistic), carol (raises at 3 s) under the
    example rubric, on shorter runs."""
    folder = write_class(tmp_path_factory.mktemp("class"), ["alice", "bob", "carol"])
    cfg = dataclasses.replace(load_config(EXAMPLE), seeds=(101, 2027), duration=12.0, time_limit=10.0)
    return folder, cfg, grade(folder, cfg, jobs=2, secret=bytes(range(32)))


def test_the_example_rubric_reads_as_its_four_tests():
    cfg = load_config(EXAMPLE)
    assert [i.test for i in cfg.rubric] == ["builds", "keeps", "accuracy", "consistency"]
    assert sum(i.points for i in cfg.rubric) == 10.0 and cfg.rubric[3].visibility == "after_due_date"


def test_results_json_validates_against_gradescopes_fields_and_agrees_with_page_and_csv(graded, tmp_path):
    _, _, board = graded
    doc = board.document()
    gs = write_gradescope(doc, tmp_path / "gs")
    assert len(gs) == 3
    write_outputs(board, tmp_path / "out")
    with open(tmp_path / "out" / "grade.csv", newline="", encoding="utf-8") as fh:
        csv_rows = {r["student"]: r for r in csv.DictReader(fh)}
    page = (tmp_path / "out" / "grade.html").read_text(encoding="utf-8")
    for path in gs:
        res = json.loads(path.read_text(encoding="utf-8"))
        jsonschema.validate(res, SCHEMA)
        student = path.parent.name
        assert len(res["tests"]) == 4 and [t["max_score"] for t in res["tests"]] == [2, 3, 3, 2]
        assert res["score"] == pytest.approx(sum(t["score"] for t in res["tests"]), abs=1e-9)
        assert all(0 <= t["score"] <= t["max_score"] for t in res["tests"])
        row = csv_rows[student]
        assert float(row["rubric_score"]) == res["score"] and float(row["rubric_max"]) == 10.0
        assert [float(row[f"rubric_{i}"]) for i in range(1, 5)] == [t["score"] for t in res["tests"]]
        assert f'data-rubric_score="{res["score"]}"' in page
        mine = (tmp_path / "out" / "students" / f"{student}.html").read_text(encoding="utf-8")
        assert f"Points: {res['score']:g} of 10" in mine
    by = {p.parent.name: json.loads(p.read_text()) for p in gs}
    carol = by["carol"]
    assert carol["score"] == 0 and all("failed" in t["output"] for t in carol["tests"])
    alice, bob = by["alice"], by["bob"]
    assert alice["tests"][0]["score"] == 2 and alice["tests"][3]["score"] == 2  # finds it, consistent
    bob_row = next(r for r in board.rows if r["student"] == "bob")
    assert bob_row["anees_verdict"] in bob["tests"][3]["output"]
    assert bob["tests"][3]["score"] == (2 if bob_row["anees_verdict"] == "consistent" else 0)
    assert alice["tests"][3]["visibility"] == "after_due_date"


def test_tracking_figures_are_the_errors_threshold_crossings():
    dt = 0.1
    err = np.zeros((50, 3))
    err[:, 0] = np.r_[np.linspace(2.0, 0.6, 10), np.full(30, 0.2), np.full(10, 0.9)]
    item = RubricItem("keeps", "k", 1.0, error_m=0.5, share=0.9, after_s=1.0)
    fig = tracking_figures(err, dt, item)
    assert fig["built_s"] == pytest.approx(1.1)  # tick 10 (the first at 0.2 m) ends at 1.1 s
    assert fig["share"] == pytest.approx(30 / 40)  # ticks 10..49: 30 of 40 within
    err[15, 0] = np.nan  # a failed tick is not within
    assert tracking_figures(err, dt, item)["share"] == pytest.approx(29 / 40)
    never = tracking_figures(np.full((5, 3), 3.0), dt, item)
    assert never["built_s"] is None and never["share"] == 0.0


def test_points_follow_the_rubrics_rules():
    rubric = parse_rubric("r.toml", [
        {"test": "builds", "within_s": 2.0, "points": 4},
        {"test": "keeps", "error_m": 0.5, "share": 0.8, "points": 2},
        {"test": "accuracy", "max_ratio": 1.5, "points": 3},
        {"test": "consistency", "points": 1}])
    assert rubric[2].zero_ratio == 3.0
    row = {"failed_runs": 0, "runs": 4, "failures": [], "rmse_over_pcrb": 2.25, "pos_rmse_m": 0.3,
           "anees": 3.1, "anees_verdict": "consistent"}
    runs = [{"built_s": 1.0, "share": 0.4}, {"built_s": 2.5, "share": 0.8},
            {"built_s": None, "share": 0.0}, {"built_s": 2.0, "share": 0.4}]
    tests = score_row(row, rubric, {0: runs, 1: runs})
    assert [t["score"] for t in tests] == [2.0, 1.0, 1.5, 1.0]  # 2 of 4 runs; 0.4/0.8; halfway; yes
    failed = score_row({**row, "failed_runs": 1, "failures": [{"reason": "boom"}]}, rubric, {})
    assert all(t["score"] == 0 and "boom" in t["output"] for t in failed)
    held = score_row({**row, "suspicious": "RMSE/PCRB 0.20"}, rubric, {0: runs, 1: runs})
    assert all(t["score"] == 0 and "suspicious" in t["output"] for t in held)


@pytest.mark.parametrize(("entry", "words"), [
    ({"test": "nope"}, "rubric[0].test = 'nope': expected one of builds, keeps"),
    ({"test": "builds"}, "rubric[0].within_s: missing"),
    ({"test": "keeps", "share": 1.5}, "rubric[0].share = 1.5: expected a share in (0, 1]"),
    ({"test": "consistency", "points": -1}, "rubric[0].points = -1"),
    ({"test": "consistency", "visibility": "always"}, "rubric[0].visibility = 'always'"),
    ({"test": "accuracy", "error_m": 1}, "rubric[0]: unknown key(s) error_m"),
])
def test_a_bad_rubric_is_one_line_naming_the_key(tmp_path, entry, words):
    cfg = tmp_path / "g.toml"
    lines = ["[[rubric]]"] + [f"{k} = {json.dumps(v)}" for k, v in entry.items()]
    cfg.write_text("\n".join(lines) + "\n")
    with pytest.raises(GradeError) as info:
        load_config(cfg)
    assert words in str(info.value) and str(cfg) in str(info.value) and "\n" not in str(info.value)


def test_autograde_writes_one_submissions_results_as_the_class_grade_scores_it(graded, tmp_path, capsys):
    folder, _, board = graded
    conf = tmp_path / "g.toml"
    text = EXAMPLE.read_text().replace("seeds = [101, 2027, 31337, 40961, 55001]", "seeds = [101, 2027]")
    conf.write_text(text.replace("duration = 60.0", "duration = 12.0")
                    .replace("time_limit = 60.0", "time_limit = 10.0"))
    secret = tmp_path / "grade.secret"
    secret.write_text(bytes(range(32)).hex() + "\n")
    secret.chmod(0o600)
    sub = tmp_path / "submission"
    sub.mkdir()
    (sub / "alice.py").write_bytes((folder / "alice.py").read_bytes())
    out = tmp_path / "results" / "results.json"
    assert main(["autograde", str(sub), "--config", str(conf), "--results", str(out),
                 "--secret-file", str(secret)]) == 0
    res = json.loads(out.read_text())
    jsonschema.validate(res, SCHEMA)
    alice = next(r for r in board.rows if r["student"] == "alice")
    expected = results_json(alice)
    assert res["tests"] == expected["tests"] and res["score"] == expected["score"]
    assert "points" in capsys.readouterr().out


def test_gradescope_without_a_rubric_is_one_line(tmp_path, capsys):
    folder = write_class(tmp_path / "class", ["alice"])
    conf = tmp_path / "g.toml"
    conf.write_text('seeds = [1]\nduration = 2.0\n')
    assert main(["grade", str(folder), "--config", str(conf), "--out", str(tmp_path / "o"),
                 "--gradescope", str(tmp_path / "gs")]) == 2
    err = capsys.readouterr().err
    assert "needs a rubric" in err and len(err.strip().splitlines()) == 1
