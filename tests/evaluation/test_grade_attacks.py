"""Grades you can trust: a class of honest students and one hostile file per
attack (tests/attacks/), graded with each student's filter in a child process of its own.

Every attack has its own assertion on the outcome: the honest students' scores are bit for
bit those of grading them alone; the attacker failed, was flagged, or did no better than an
honest EKF; the right student is blamed; the working folder is untouched; the grader's
output stays bounded. No assertion depends on the machine's speed (time limits are CPU
time, and generous); runs are short (4 s of simulated time, two seeds)."""

from __future__ import annotations

import dataclasses
import os
import shutil
from pathlib import Path

import pytest

from beacon_sim.evaluation.grading import LOG_BYTES, GradeConfig, grade, write_outputs
from beacon_sim.hosting.containment import bwrap_problem

ATTACKS = Path(__file__).parents[1] / "attacks"
HONEST = ("honest", "honest_tuned")
HOSTILE = ("frame_walk", "gc_search", "truth_tamper", "patch_grading", "os_exit", "file_writes",
           "global_rng", "helper_last", "functions", "forge_reply")
CONFIG = GradeConfig(scenarios=("default",), seeds=(0, 1), duration=4.0, time_limit=30.0)
FIGURES = ("pos_rmse_m", "heading_rmse_rad", "anees", "anees_verdict", "rmse_over_pcrb",
           "failed_runs", "plot")


def _klass(folder: Path, stems) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for stem in stems:
        shutil.copyfile(ATTACKS / f"{stem}.py", folder / f"{stem}.py")
    return folder


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    """The grader's working directory during the class's grading, with a victim file."""
    d = tmp_path_factory.mktemp("cwd")
    (d / "victim.txt").write_text("precious")
    return d


@pytest.fixture(scope="module")
def klass(tmp_path_factory):
    folder = _klass(tmp_path_factory.mktemp("class"), HONEST + HOSTILE)
    (folder / "victim.txt").write_text("precious")
    return folder


@pytest.fixture(scope="module")
def board(klass, workdir):
    before = os.getcwd()
    os.chdir(workdir)
    try:
        b = grade(klass, CONFIG, jobs=2)
    finally:
        os.chdir(before)
    return b


@pytest.fixture(scope="module")
def alone(tmp_path_factory):
    return grade(_klass(tmp_path_factory.mktemp("honest"), HONEST), CONFIG, jobs=2)


def _row(board, student):
    return next(r for r in board.rows if r["student"] == student)


def test_honest_scores_are_bit_identical_to_grading_them_alone(board, alone):
    for name in HONEST:
        a, b = _row(board, name), _row(alone, name)
        assert {k: a[k] for k in FIGURES} == {k: b[k] for k in FIGURES}, name
        assert a["failed_runs"] == 0 and not a["flags"], (name, a["flags"])


def test_the_isolated_host_gives_the_in_process_numbers(alone, tmp_path):
    from beacon_sim.core.scenario import load_scenario
    from beacon_sim.evaluation.montecarlo import one_run
    from beacon_sim.evaluation.summary import evaluate

    sc = load_scenario("default")
    spec = f"{ATTACKS / 'honest.py'}:MyEkf"
    runs = [one_run(sc, [spec], {}, seed, 4.0, index=i, keep_means=i == 0) for i, seed in enumerate((0, 1))]
    meta, _ = evaluate(sc, runs)
    fr = next(iter(meta["filters"].values()))
    row = _row(alone, "honest")
    assert (fr["pos_rmse_m"], fr["anees"]) == (row["pos_rmse_m"], row["anees"])


@pytest.mark.parametrize("attacker", ["frame_walk", "gc_search", "truth_tamper"])
def test_the_truth_is_out_of_reach(board, attacker):
    """Frames, gc and truth arrays: in its own process the attacker finds nothing and
    scores exactly as the honest EKF it wraps (no better), and is not ranked above it."""
    row, honest = _row(board, attacker), _row(board, "honest")
    assert row["failed_runs"] == 0, row["failures"]
    assert row["pos_rmse_m"] == honest["pos_rmse_m"] and row["anees"] == honest["anees"]
    assert not row["suspicious"]


def test_patching_the_grading_module_at_import_changes_nobody_else(board, alone):
    row = _row(board, "patch_grading")
    assert row["failed_runs"] == 0 and row["pos_rmse_m"] == _row(board, "honest")["pos_rmse_m"]
    for name in HONEST:
        assert _row(board, name)["pos_rmse_m"] == _row(alone, name)["pos_rmse_m"]


def test_os_exit_fails_its_own_student_with_the_real_reason(board):
    row = _row(board, "os_exit")
    assert row["failed_runs"] == 2 and row["pos_rmse_m"] is None
    assert all("exited with status 3" in f["reason"] for f in row["failures"]), row["failures"]
    others = [r for r in board.rows if r["student"] not in ("os_exit", "forge_reply")]
    assert not any("exited" in f["reason"] or "died" in f["reason"] for r in others for f in r["failures"])
    assert board.rows[-1]["student"] in ("os_exit", "forge_reply")  # below every working filter


def test_a_forged_answer_on_the_pipe_fails_its_own_student(board):
    row = _row(board, "forge_reply")
    assert row["failed_runs"] == 2 and all("broke the protocol" in f["reason"] for f in row["failures"])


def test_files_in_the_working_directory_and_the_class_folder_are_untouched(board, klass, workdir):
    for folder in (workdir, klass):
        assert (folder / "victim.txt").read_text() == "precious"
        assert not (folder / "pwned.txt").exists()
    assert _row(board, "file_writes")["failed_runs"] == 0  # graded all the same


def test_a_global_rng_filter_is_reproducible_and_flagged(board, tmp_path):
    row = _row(board, "global_rng")
    assert row["global_rng"] is True and any("global" in f for f in row["flags"])
    # graded alone with the class's secret (the grader seeds the global generators from it,
    # never from the run's seed): the same figures bit for bit
    again = grade(_klass(tmp_path / "again", ["global_rng"]), CONFIG, jobs=1,
                  secret=bytes.fromhex(board.secret))
    assert {k: _row(again, "global_rng")[k] for k in FIGURES} == {k: row[k] for k in FIGURES}
    assert _row(board, "honest")["global_rng"] is False


def test_the_filter_class_is_chosen_and_functions_are_a_filter(board):
    honest = _row(board, "honest")
    for name in ("helper_last", "functions"):
        row = _row(board, name)
        assert row["failed_runs"] == 0, row["failures"]
        assert row["pos_rmse_m"] == honest["pos_rmse_m"] and row["anees"] == honest["anees"]
    assert _row(board, "functions")["form"] == "functions"
    assert _row(board, "helper_last")["form"] == "class"


def test_the_page_shows_the_sandbox_the_logs_and_no_attacker_above_an_honest_student(board, tmp_path):
    write_outputs(board, tmp_path)
    page = (tmp_path / "grade.html").read_text()
    assert board.sandbox in ("bwrap", "process") and "a process of its own" in page
    ranks = {r["student"]: r["rank"] for r in board.rows}
    assert ranks["os_exit"] > max(ranks[n] for n in HONEST)
    assert (tmp_path / "grade.csv").read_text().count("\n") == len(HONEST + HOSTILE) + 1


def test_a_print_flood_is_cut_and_kept_off_the_graders_output(tmp_path, capfd):
    b = grade(_klass(tmp_path / "flood", ["print_flood"]), CONFIG, jobs=1)
    out, err = capfd.readouterr()
    row = _row(b, "print_flood")
    assert row["failed_runs"] == 0, row["failures"]
    assert len(out) + len(err) < 10_000  # 20 KB a step x 160 steps went to the log, not here
    log = b.logs["print_flood"]
    assert "[output cut at" in log and len(log.encode()) <= LOG_BYTES + 300
    write_outputs(b, tmp_path / "out")
    assert (tmp_path / "out" / "logs" / "print_flood.log").stat().st_size <= LOG_BYTES + 300


@pytest.mark.parametrize("sandbox", ["process", "bwrap"])
def test_both_containment_levels_grade_the_same(tmp_path, sandbox, alone):
    if sandbox == "bwrap" and bwrap_problem():
        pytest.skip(f"no bubblewrap sandbox here: {bwrap_problem()}")
    import dataclasses

    cfg = dataclasses.replace(CONFIG, sandbox=sandbox, allow_unisolated=True)
    b = grade(_klass(tmp_path / "c", ["honest", "os_exit", "file_writes"]), cfg, jobs=2)
    assert b.sandbox == sandbox
    assert {k: _row(b, "honest")[k] for k in FIGURES} == {k: _row(alone, "honest")[k] for k in FIGURES}
    assert "exited with status 3" in _row(b, "os_exit")["failures"][0]["reason"]
    assert not (tmp_path / "c" / "pwned.txt").exists()


def test_a_result_far_below_the_bound_is_suspicious_and_kept_out_of_the_ranking(tmp_path, alone):
    """Re-simulating a shipped scenario with guessed small seeds (the one way to the truth
    left at the process level) gives a result far below the PCRB: flagged, not ranked."""
    import dataclasses

    b = grade(_klass(tmp_path / "c", ["honest", "resimulate"]),
              dataclasses.replace(CONFIG, sandbox="process", allow_unisolated=True), jobs=2)
    row, honest = _row(b, "resimulate"), _row(b, "honest")
    if row["pos_rmse_m"] is not None and row["pos_rmse_m"] < honest["pos_rmse_m"]:
        assert row["suspicious"] and "RMSE/PCRB" in row["suspicious"], row
        assert row["rank"] > honest["rank"] and any(f.startswith("suspicious") for f in row["flags"])
    assert {k: honest[k] for k in FIGURES} == {k: _row(alone, "honest")[k] for k in FIGURES}
    write_outputs(b, tmp_path / "out")
    assert "SUSPICIOUS" in (tmp_path / "out" / "grade.csv").read_text()


def test_a_page_per_student_and_pseudonyms_on_the_class_page(board, tmp_path):
    import csv

    write_outputs(board, tmp_path / "named")
    page = (tmp_path / "named" / "students" / "os_exit.html").read_text()
    assert "exited with status 3" in page and "../grade.html" in page and "<svg" in page
    assert 'href="students/honest.html"' in (tmp_path / "named" / "grade.html").read_text()
    anon = dataclasses.replace(board, config={**board.config, "pseudonyms": True})
    write_outputs(anon, tmp_path / "anon")
    html = (tmp_path / "anon" / "grade.html").read_text()
    with open(tmp_path / "anon" / "pseudonyms.csv", newline="") as fh:
        mapping = {r["student"]: r["pseudonym"] for r in csv.DictReader(fh)}
    assert set(mapping) == set(HONEST + HOSTILE)
    for student, alias in mapping.items():
        assert f'data-student="{student}"' not in html and f'data-student="{alias}"' in html
        assert (tmp_path / "anon" / "students" / f"{alias}.html").exists()


def test_regrading_reuses_unchanged_students_and_runs_a_changed_file(tmp_path, alone):
    klass = _klass(tmp_path / "c", HONEST)
    cache = tmp_path / "cache"
    first = grade(klass, CONFIG, jobs=2, cache=cache)
    assert first.cached_students == []
    shutil.copyfile(ATTACKS / "os_exit.py", klass / "honest_tuned.py")  # a corrected (here: broken) file
    assert grade(klass, CONFIG, jobs=1, cache=cache).cached_students == []  # a new secret: all again
    again = grade(klass, CONFIG, jobs=2, cache=cache, secret=bytes.fromhex(first.secret))
    assert again.cached_students == ["honest"]  # the kept secret: the unchanged file reused
    assert {k: _row(again, "honest")[k] for k in FIGURES} == {k: _row(alone, "honest")[k] for k in FIGURES}
    assert "exited with status 3" in _row(again, "honest_tuned")["failures"][0]["reason"]


def test_team_scenarios_host_each_robots_filter_in_a_child_too(tmp_path):
    """On a team scenario the student's filter is every robot's own, each copy in a child
    process: an honest EKF scores exactly as the built-in reference, the frame walker finds
    nothing, os._exit fails its own student with the real reason."""
    cfg = GradeConfig(scenarios=("team_sparse",), seeds=(0,), duration=3.0, time_limit=30.0)
    b = grade(_klass(tmp_path / "c", ["honest", "frame_walk", "os_exit"]), cfg, jobs=2)
    ref = b.reference["team_sparse"]["pos_rmse_m"]
    assert _row(b, "honest")["pos_rmse_m"] == ref == _row(b, "frame_walk")["pos_rmse_m"]
    assert "exited with status 3" in _row(b, "os_exit")["failures"][0]["reason"]
    assert b.team_in_process == []


def test_the_probes_find_determinism_and_the_use_of_readings(board, tmp_path):
    """The probes (the first run fed again, and fed no readings) ride in the first batch:
    the honest EKF is deterministic and uses its readings; dead reckoning uses none; the
    global-RNG filter (graded seed by seed) is not deterministic."""
    honest = _row(board, "honest")
    assert honest["deterministic"] is True and honest["readings_used"] is True
    assert _row(board, "global_rng")["deterministic"] is False
    folder = tmp_path / "blind"
    folder.mkdir()
    (folder / "blind.py").write_text("from beacon_sim.filters.gaussian.dead_reckoning "
                                     "import DeadReckoning\n\n\n"
                                     "class Blind(DeadReckoning):\n    pass\n")
    row = _row(grade(folder, CONFIG, jobs=1), "blind")
    assert row["failed_runs"] == 0 and row["readings_used"] is False and row["deterministic"] is True
    assert any("uses none of the readings" in f for f in row["flags"])
