"""``beacon-sim autograde SUBMISSION --config grade.toml [--results PATH]``: one student's
submission graded as ``grade`` grades a class, written as the ``results.json`` Gradescope's
autograder harness reads (default ``/autograder/results/results.json``): what a course's
``run_autograder`` calls (docs/grading.md, "A grade a course platform takes").

SUBMISSION is the filter file, or a folder holding exactly one ``.py`` file (Gradescope's
``/autograder/submission``). The file is graded alone in a private folder, against the
config's rubric; the exit status is 0 whenever results.json was written (a failed filter is
a score, not an error), 2 (one line) when it could not be.
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

from beacon_sim.errors import UsageError
from beacon_sim.evaluation.grading import GradeError, grade, load_config, read_secret
from beacon_sim.evaluation.grading.gradescope import GRADESCOPE_RESULTS, results_json, write_results


def submission_file(path: Path) -> Path:
    """The filter file of a submission: the file itself, or the one ``.py`` file of a folder."""
    if path.is_file():
        return path
    if not path.is_dir():
        raise UsageError(f"{path}: no such file or folder (expected the submitted filter file)")
    found = sorted(p for p in path.iterdir() if p.suffix == ".py" and p.is_file())
    if len(found) != 1:
        raise UsageError(f"{path}: expected exactly one .py file in the submission, found "
                         f"{len(found)}{': ' + ', '.join(p.name for p in found) if found else ''}")
    return found[0]


def autograde_command(args: argparse.Namespace) -> int:
    """Grade one submission and write its results.json; print where and the score."""
    try:
        cfg = load_config(args.config)
        if not cfg.rubric:
            raise GradeError(f"{args.config}: no [[rubric]] tables: autograde scores a rubric "
                             "(docs/grading.md, \"A grade a course platform takes\")")
        secret = read_secret(args.secret_file) if args.secret_file else None
    except GradeError as exc:
        raise UsageError(str(exc)) from None
    src = submission_file(Path(args.submission))
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="beacon-sim-autograde-") as tmp:
        folder = Path(tmp) / "class"
        folder.mkdir()
        shutil.copyfile(src, folder / src.name)
        try:
            board = grade(folder, cfg, jobs=1, cache=None, secret=secret)
        except GradeError as exc:
            raise UsageError(str(exc)) from None
    row = board.rows[0]
    doc = results_json(row, time.perf_counter() - t0)
    out = Path(args.results) if args.results else GRADESCOPE_RESULTS
    try:
        write_results(doc, out)
    except (GradeError, OSError) as exc:
        raise UsageError(f"{out}: cannot write results.json: {exc}") from None
    print(f"{src.name}: {doc['score']:g} of {row['rubric_max']:g} points "
          f"({len(doc['tests'])} tests); wrote {out}")
    return 0
