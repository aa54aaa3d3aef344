"""No CSV the program writes carries a spreadsheet formula: a student's file named
``=2+3*cmd|' -C calc'!A0.py`` lands in grade.csv as text, and a CSV the program reads back
(an export) gives the text as it was."""

from __future__ import annotations

import csv
import io
import random

import numpy as np
from student_filters import write_class

from beacon_sim.core.csv_cells import FORMULA_STARTS, csv_writer, guard_cell, needs_guard, unguard_cell
from beacon_sim.evaluation.grading import GradeConfig, grade, write_outputs

EVIL = "=2+3*cmd|' -C calc'!A0"


def _is_formula(cell: str) -> bool:
    """What a spreadsheet runs: a cell whose first character starts a formula, unless it
    reads as a plain number."""
    if not cell or cell[0] not in FORMULA_STARTS:
        return False
    try:
        float(cell)
    except ValueError:
        return True
    return False


def test_guarded_cells_are_never_formulas_and_come_back_exactly():
    rng = random.Random(7)
    alphabet = "=+-@'\t\r a1.e|!"
    texts = ["".join(rng.choice(alphabet) for _ in range(rng.randint(0, 6))) for _ in range(3000)]
    texts += [EVIL, "-1.5", "+2", "-inf", "'=x", "''=x", "@SUM(A1)", "'plain"]
    for t in texts:
        g = guard_cell(t)
        assert not _is_formula(g), (t, g)
        assert unguard_cell(g) == t, (t, g)
    assert guard_cell("-1.5") == "-1.5" and guard_cell(-1.5) == -1.5  # numbers stay numbers
    assert guard_cell(EVIL) == "'" + EVIL and needs_guard("'" + EVIL)


def test_the_writer_guards_every_text_cell():
    fh = io.StringIO()
    csv_writer(fh).writerow([EVIL, 3, "-2", "@x", "ok"])
    row = next(csv.reader(io.StringIO(fh.getvalue())))
    assert row == ["'" + EVIL, "3", "-2", "'@x", "ok"]


def test_a_file_named_like_a_formula_is_text_in_grade_csv(tmp_path):
    klass = tmp_path / "class"
    write_class(klass, ["alice"])
    (klass / "alice.py").rename(klass / f"{EVIL}.py")
    board = grade(klass, GradeConfig(scenarios=("default",), seeds=(0,), duration=2.0, time_limit=5.0),
                  jobs=1, secret=bytes(32))
    out = tmp_path / "out"
    write_outputs(board, out)
    with open(out / "grade.csv", newline="", encoding="utf-8") as fh:
        rows = list(csv.reader(fh))
    cells = [c for r in rows for c in r]
    assert "'" + EVIL in cells and "'" + EVIL + ".py" in cells  # the student and the file, as text
    assert not [c for c in cells if _is_formula(c)], [c for c in cells if _is_formula(c)]


def test_an_export_reads_back_a_guarded_name_as_it_was(tmp_path):
    from beacon_sim.io.tables import read_table_csv, write_table_csv

    table = {"filter": np.array([EVIL, "ekf"]), "x_m": np.array([-1.5, 2.0])}
    path = write_table_csv(table, tmp_path / "t.csv")
    assert "'" + EVIL in path.read_text()
    back = read_table_csv(path, "estimates")
    assert list(back["filter"]) == [EVIL, "ekf"] and list(back["x_m"]) == [-1.5, 2.0]
