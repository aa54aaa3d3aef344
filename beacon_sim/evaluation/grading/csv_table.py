"""``grade.csv``: one row per student (:data:`CSV_COLUMNS`, the SLAM columns on a SLAM
assignment).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from beacon_sim.core.csv_cells import csv_writer
from beacon_sim.core.files import (
    atomic_write,
)
from beacon_sim.evaluation.grading.config import GradeError
from beacon_sim.evaluation.grading.scoring import status

CSV_COLUMNS = ("rank", "student", "file", "status", "pos_rmse_m", "heading_rmse_rad", "anees",
               "anees_verdict", "verdict", "rmse_over_pcrb", "us_per_step", "failed_runs", "runs",
               "failures", "suspicious", "global_rng", "deterministic", "heading_wrapped", "readings_used",
               "flags")
#: The map columns a SLAM assignment adds (after :data:`CSV_COLUMNS`; seed means over the
#: SLAM scenarios; empty for a failed filter, and the map's for a filter without one).
SLAM_CSV_COLUMNS = ("ate_m", "map_gospa_m", "joint_nees")
#: The columns a rubric adds (last): the points, the most there are, and each test's points
#: in a column of its own, ``rubric_1``... in the rubric's order (what results.json says).
RUBRIC_CSV_COLUMNS = ("rubric_score", "rubric_max")


def _yes_no(v: object) -> str:
    return "" if v is None else ("yes" if v else "no")


def failure_text(f: dict[str, Any]) -> str:
    where = "" if f.get("seed") is None else f"{f['scenario']} seed {f['seed']}"
    at = "" if f.get("time_s") is None else f" at {f['time_s']:.2f} s"
    return f"{where}{at}: {f['reason']}" if where else str(f["reason"])


def write_csv(board: dict[str, Any], path: Path) -> Path:
    """One row per student, in rank order; a failed student's figures are empty cells."""
    slam = bool(board.get("slam_reference"))
    with atomic_write(path, "w", newline="", what="grade table", error=GradeError) as fh:
        w = csv_writer(fh)
        rubric = board["config"].get("rubric") or ()
        tests = tuple(f"rubric_{i + 1}" for i in range(len(rubric)))
        w.writerow(CSV_COLUMNS + (SLAM_CSV_COLUMNS if slam else ())
                   + ((*RUBRIC_CSV_COLUMNS, *tests) if rubric else ()))
        for r in board["rows"]:
            extra = ["" if r.get(k) is None else r[k] for k in SLAM_CSV_COLUMNS] if slam else []
            if rubric:
                extra += [r["rubric_score"], r["rubric_max"], *(t["score"] for t in r["rubric"])]
            w.writerow([r["rank"], r["student"], r["file"], status(r),
                        *("" if r[k] is None else r[k] for k in ("pos_rmse_m", "heading_rmse_rad",
                                                                 "anees")),
                        r["anees_verdict"], r.get("verdict", r["anees_verdict"]),
                        "" if r["rmse_over_pcrb"] is None else r["rmse_over_pcrb"],
                        "" if r["us_per_step"] is None else f"{r['us_per_step']:.1f}",
                        r["failed_runs"], r["runs"],
                        " | ".join(failure_text(f) for f in r["failures"][:5]),
                        r.get("suspicious") or "", *(_yes_no(r.get(k)) for k in (
                            "global_rng", "deterministic", "heading_wrapped", "readings_used")),
                        " | ".join(r.get("flags", [])), *extra])
    return path
