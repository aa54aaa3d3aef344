"""Everything a grade writes in its output folder (:func:`write_outputs`): the CSV, the HTML
pages, ``grade.json``, the logs, the pseudonyms and the grade's secret.
"""

from __future__ import annotations

import json
from pathlib import Path

from beacon_sim.core.csv_cells import csv_writer
from beacon_sim.core.files import (
    atomic_write,
    write_text_atomic,
)
from beacon_sim.evaluation.grading.board import GradeResult
from beacon_sim.evaluation.grading.config import GradeError
from beacon_sim.evaluation.grading.csv_table import write_csv
from beacon_sim.evaluation.grading.html_pages import shown_names, write_html, write_student_page
from beacon_sim.evaluation.grading.secret import SECRET_FILE, write_secret


def write_outputs(result: GradeResult, out: Path) -> list[Path]:
    """``grade.csv``, ``grade.html``, ``grade.json`` (the rows without the plots), a page per
    student (``students/``), the logs (``logs/``), with pseudonyms ``pseudonyms.csv``, and
    the grade's secret in ``grade.secret`` (:data:`SECRET_FILE`, the owner's only; never in
    ``grade.json``, which names it by its fingerprint) in ``out``."""
    board = result.document()
    out.mkdir(parents=True, exist_ok=True)
    if board.get("secret"):
        write_secret(str(board["secret"]), out / SECRET_FILE)
    logs = board.get("logs") or {}
    shown = shown_names(board)
    if logs:
        (out / "logs").mkdir(exist_ok=True)
        for student, text in logs.items():
            write_text_atomic(out / "logs" / f"{shown.get(student, student)}.log", text, error=GradeError)
    (out / "students").mkdir(exist_ok=True)
    for r in board["rows"]:
        write_student_page(board, r, out / "students" / f"{shown[r['student']]}.html", shown[r["student"]],
                           logs.get(r["student"], ""))
    if board["config"].get("pseudonyms"):
        with atomic_write(out / "pseudonyms.csv", "w", newline="", error=GradeError) as fh:
            w = csv_writer(fh)
            w.writerow(("pseudonym", "student", "file"))
            for r in board["rows"]:
                w.writerow((shown[r["student"]], r["student"], r["file"]))
    doc = {k: v for k, v in board.items() if k not in ("rows", "logs", "secret")}
    doc["rows"] = [{k: v for k, v in r.items() if k != "plot"} for r in board["rows"]]
    write_text_atomic(out / "grade.json", json.dumps(doc, indent=1, default=float), error=GradeError)
    return [write_csv(board, out / "grade.csv"), write_html(board, out / "grade.html"),
            out / "grade.json"]
