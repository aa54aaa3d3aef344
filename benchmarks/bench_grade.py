"""Grading a class with each student's filter in a process of its own (issue 23): a class of
36 files (honest variations of the EKF and the hostile files of tests/attacks and
tests/student_filters), graded locally and on a Dask LocalCluster; every honest student's
figures compared, bit for bit, with grading the honest students alone; and the cost of a
graded run with the isolation against the in-process path of an earlier commit (``--base``:
a folder holding that commit's ``beacon_sim`` and ``scenarios``, e.g. made with
``git archive 62f69b5 beacon_sim scenarios assets | tar -x -C /tmp/base``).

    python benchmarks/bench_grade.py [--seeds 3] [--duration 60] [--base /tmp/base] [--no-dask]

Prints FIGURE lines (name, value, unit) and the ratios.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from beacon_sim.evaluation.grading import GradeConfig, grade  # noqa: E402
from tests.student_filters import source as student_source  # noqa: E402

ATTACKS = ROOT / "tests" / "attacks"
HOSTILE_ATTACKS = ("frame_walk", "gc_search", "truth_tamper", "patch_grading", "os_exit",
                   "file_writes", "print_flood", "global_rng", "resimulate")
HOSTILE_STUDENTS = ("carol", "heidi", "mallory")
FIGURES = ("pos_rmse_m", "heading_rmse_rad", "anees", "anees_verdict", "rmse_over_pcrb", "failed_runs")


def honest_source(k: int) -> str:
    """The k-th honest variation: the EKF with its own gate (chi-square 0 = none, or 6..28)."""
    gate = 0.0 if k % 3 == 0 else 6.0 + k
    joseph = "True" if k % 2 == 0 else "False"
    return ("from typing import ClassVar\n\nfrom beacon_sim.filters.ekf import ExtendedKalmanFilter\n\n\n"
            "class MyEkf(ExtendedKalmanFilter):\n"
            f"    defaults: ClassVar[dict] = {{'gate_chi2': {gate}, 'joseph': {joseph}}}\n")


def write_class(folder: Path, honest: int, hostile: bool) -> list[str]:
    folder.mkdir(parents=True, exist_ok=True)
    names = []
    for k in range(honest):
        (folder / f"honest{k:02d}.py").write_text(honest_source(k))
        names.append(f"honest{k:02d}")
    for extra in ("functions", "helper_last", "honest_tuned"):
        shutil.copyfile(ATTACKS / f"{extra}.py", folder / f"{extra}.py")
        names.append(extra)
    if hostile:
        for a in HOSTILE_ATTACKS:
            shutil.copyfile(ATTACKS / f"{a}.py", folder / f"{a}.py")
        for s in HOSTILE_STUDENTS:
            (folder / f"{s}.py").write_text(student_source(s))
    return names


def figures(board: dict, names: list[str]) -> dict[str, tuple]:
    return {r["student"]: tuple(r[k] for k in FIGURES) for r in board["rows"] if r["student"] in names}


def base_grade(base: Path, folder: Path, cfg: GradeConfig, jobs: int | None) -> float:
    """Wall time [s] of the in-process grade of the commit in ``base`` (a subprocess)."""
    code = (f"import time; from beacon_sim.evaluation.grading import GradeConfig, grade; "
            f"t = time.perf_counter(); grade({str(folder)!r}, GradeConfig(scenarios={cfg.scenarios!r}, "
            f"seeds={cfg.seeds!r}, duration={cfg.duration!r}, time_limit={cfg.time_limit!r}), jobs={jobs}); "
            f"print(time.perf_counter() - t)")
    env = {**os.environ, "PYTHONPATH": str(base), "PYTHONDONTWRITEBYTECODE": "1"}
    out = subprocess.run([sys.executable, "-B", "-c", code], env=env, capture_output=True, text=True,
                         check=True, cwd=tempfile.gettempdir())
    return float(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--time-limit", type=float, default=10.0)
    ap.add_argument("--jobs", type=int, default=None,
                    help="students at once (default: each grade's own default)")
    ap.add_argument("--base", type=Path)
    ap.add_argument("--no-dask", action="store_true")
    args = ap.parse_args()
    cfg = GradeConfig(scenarios=("default",), seeds=tuple(range(args.seeds)), duration=args.duration,
                      time_limit=args.time_limit)
    tmp = Path(tempfile.mkdtemp(prefix="bench-grade-"))
    klass = tmp / "class"
    honest = write_class(klass, 21, hostile=True)
    n = len(list(klass.glob("*.py")))
    print(f"FIGURE class_files {n} files ({len(honest)} honest)")

    t0 = time.perf_counter()
    board = grade(klass, cfg, jobs=args.jobs)
    local_s = time.perf_counter() - t0
    print(f"FIGURE grade_local_wall {local_s:.1f} s (sandbox {board['sandbox']}, jobs "
          f"{args.jobs or 'default'}, {args.seeds} seeds x {args.duration:g} s)")
    write_class(tmp / "alone", 21, hostile=False)
    alone = grade(tmp / "alone", cfg, jobs=args.jobs)
    same = figures(board, honest) == figures(alone, honest)
    print(f"FIGURE honest_identical_to_alone_local {same} ({len(honest)} students)")
    print("ROWS " + json.dumps([(r["rank"], r["student"], r["pos_rmse_m"], r.get("suspicious"),
                                 [f["reason"] for f in r["failures"][:1]], r.get("flags"))
                                for r in board["rows"]], default=str))

    if not args.no_dask:
        from dask.distributed import Client, LocalCluster

        with LocalCluster(n_workers=args.jobs or 2, threads_per_worker=1, processes=True,
                          dashboard_address=None) as cluster, Client(cluster) as client:
            t0 = time.perf_counter()
            remote = grade(klass, cfg, scheduler=client)
            dask_s = time.perf_counter() - t0
        print(f"FIGURE grade_dask_wall {dask_s:.1f} s (LocalCluster {args.jobs or 2} workers x 1 thread)")
        print(f"FIGURE honest_identical_to_alone_dask {figures(remote, honest) == figures(alone, honest)}")
        everyone = [r["student"] for r in board["rows"]]
        print(f"FIGURE dask_identical_to_local {figures(remote, everyone) == figures(board, everyone)}")

    if args.base is not None:  # the cost of a graded run: the honest class, isolated vs in process
        hon = tmp / "alone"
        runs = len(honest) * args.seeds
        wall: dict[str, list[float]] = {"iso": [], "base": []}
        for _ in range(2):  # interleaved, best of 2: the machine's load drifts
            t0 = time.perf_counter()
            grade(hon, cfg, jobs=args.jobs)
            wall["iso"].append(time.perf_counter() - t0)
            wall["base"].append(base_grade(args.base, hon, cfg, args.jobs))
        iso, inproc = min(wall["iso"]), min(wall["base"])
        print(f"FIGURE graded_run_isolated {iso / runs * 1e3:.0f} ms per run ({runs} runs, simulation "
              "once per seed, child start, probes and scoring included; best of 2)")
        print(f"FIGURE graded_run_in_process_base {inproc / runs * 1e3:.0f} ms per run (the base "
              "commit's grade, each run simulating its own truth; best of 2)")
        print(f"FIGURE isolated_over_in_process {iso / inproc:.2f} x (wall time, jobs: "
              f"{args.jobs or 'each default'})")
    shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
