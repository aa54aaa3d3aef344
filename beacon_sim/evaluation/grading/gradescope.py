"""Gradescope's autograder output: one ``results.json`` per student from the rows' rubric
(:mod:`~beacon_sim.evaluation.grading.rubric`), in the format Gradescope documents
("Autograder Specifications", gradescope-autograders.readthedocs.io/en/latest/specs/):
the submission's ``score``, ``output`` and ``stdout_visibility``, and per test ``name``,
``score``, ``max_score``, ``status``, ``output`` and ``visibility``.

:func:`results_json` is one student's document; :func:`write_gradescope` writes
``DIR/STUDENT/results.json`` for a class (``grade --gradescope DIR``), and
``beacon-sim autograde`` writes one (the ``run_autograder`` entry, docs/grading.md).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from beacon_sim.core.files import write_text_atomic
from beacon_sim.evaluation.grading.config import GradeError
from beacon_sim.evaluation.grading.scoring import status

#: Where Gradescope's harness reads the results of ``run_autograder``.
GRADESCOPE_RESULTS = Path("/autograder/results/results.json")
#: The fields Gradescope documents for results.json and for each of its tests: what
#: :func:`results_json` may write (tests/test_gradescope.py validates against them).
TOP_FIELDS = ("score", "execution_time", "output", "output_format", "test_output_format",
              "test_name_format", "visibility", "stdout_visibility", "extra_data", "tests", "leaderboard")
TEST_FIELDS = ("score", "max_score", "status", "name", "name_format", "number", "output", "output_format",
               "tags", "visibility", "extra_data")


def _summary(row: dict[str, Any]) -> str:
    """The submission's output: its status, figures and warnings, as the class page says them."""
    st = status(row)
    lines = [f"status: {st}"]
    if not row["failed_runs"]:
        lines.append(f"position RMSE {row['pos_rmse_m']:.4f} m; heading RMSE "
                     f"{row['heading_rmse_rad']:.4f} rad; "
                     f"ANEES {'-' if row['anees'] is None else format(row['anees'], ',.2f')} "
                     f"({row['verdict']}); RMSE/PCRB "
                     f"{'-' if row['rmse_over_pcrb'] is None else format(row['rmse_over_pcrb'], '.2f')}")
    for f in row["failures"][:5]:
        where = "" if f.get("seed") is None else f"{f['scenario']} seed {f['seed']}: "
        lines.append(f"failed: {where}{f['reason']}")
    lines += [f"warning: {flag}" for flag in row.get("flags", [])]
    for limit in row.get("limits_hit", []):
        lines.append(f"limit hit: {limit}")
    return "\n".join(lines)


def results_json(row: dict[str, Any], execution_time_s: float | None = None) -> dict[str, Any]:
    """One student's results.json: the rubric's tests and their sum (the row's
    ``rubric_score``, which the page and the CSV show too)."""
    if "rubric" not in row:
        raise GradeError("a Gradescope results.json needs a rubric: add [[rubric]] tables to the "
                         "grade config (docs/grading.md, \"A grade a course platform takes\")")
    tests = [{"name": t["name"], "score": t["score"], "max_score": t["max_score"],
              "status": "passed" if t["score"] >= t["max_score"] else "failed",
              "output": t["output"] or "", "visibility": t["visibility"]} for t in row["rubric"]]
    doc: dict[str, Any] = {"score": row["rubric_score"], "output": _summary(row),
                           "stdout_visibility": "hidden", "tests": tests}
    if execution_time_s is not None:
        doc["execution_time"] = max(0, round(execution_time_s))
    return doc


def write_gradescope(board: dict[str, Any], out: Path) -> list[Path]:
    """``out/STUDENT/results.json`` for every student of a graded class (the teacher's real
    names: the folders are for uploading, not for the class to see)."""
    if not board["config"].get("rubric"):
        raise GradeError("--gradescope needs a rubric: add [[rubric]] tables to the grade config "
                         "(docs/grading.md, \"A grade a course platform takes\")")
    written = []
    for row in board["rows"]:
        path = out / row["student"] / "results.json"
        path.parent.mkdir(parents=True, exist_ok=True)
        write_results(results_json(row), path)
        written.append(path)
    return written


def write_results(doc: dict[str, Any], path: Path) -> Path:
    """One results.json, whole or not at all."""
    path.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(path, json.dumps(doc, indent=1), what="Gradescope results", error=GradeError)
    return path
