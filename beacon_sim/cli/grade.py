"""``beacon-sim grade DIR [--config grade.toml] [--out DIR] [--jobs J] [--scheduler ADDRESS]
[--time-limit S] [--strict]``: every filter file in a folder over the same scenarios and
seeds; writes grade.csv, grade.html (the leaderboard) and grade.json (docs/grading.md).
On a team scenario each student's filter is every robot's own filter, graded beside the
built-in independent EKF (docs/multi-robot.md)."""

from __future__ import annotations

import argparse
import dataclasses
import math
import time
from pathlib import Path

from beacon_sim.core.optional import install_hint
from beacon_sim.errors import UsageError
from beacon_sim.evaluation.grading import (
    SECRET_FILE,
    GradeError,
    grade,
    load_config,
    read_secret,
    write_outputs,
)
from beacon_sim.evaluation.grading.gradescope import write_gradescope
from beacon_sim.evaluation.montecarlo import ClusterError
from beacon_sim.runs.progress import Progress


def grade_command(args: argparse.Namespace) -> int:
    """Grade the folder ``args.dir``; exit status 0 (1 with ``--strict`` when any filter failed)."""
    if args.jobs is not None and args.jobs < 1:
        raise UsageError(f"--jobs {args.jobs}: expected a number of processes >= 1")
    try:
        cfg = load_config(args.config)
    except GradeError as exc:
        raise UsageError(str(exc)) from None
    if args.time_limit is not None:
        if not (args.time_limit > 0 and math.isfinite(args.time_limit)):
            raise UsageError(f"--time-limit {args.time_limit}: expected a positive number of seconds")
        cfg = dataclasses.replace(cfg, time_limit=args.time_limit)
    if getattr(args, "sandbox", None):
        cfg = dataclasses.replace(cfg, sandbox=args.sandbox)
    if getattr(args, "pseudonyms", False):
        cfg = dataclasses.replace(cfg, pseudonyms=True)
    if getattr(args, "allow_unisolated", False):
        cfg = dataclasses.replace(cfg, allow_unisolated=True)
    scheduler = args.scheduler
    if scheduler is not None:
        try:
            import dask.distributed  # noqa: F401
        except ImportError:
            raise UsageError(install_hint("dask", "--scheduler")) from None
    out = Path(args.out) if args.out else Path(args.dir) / "grade_out"
    secret, whence = _secret(args, out)
    bar: list[Progress] = []  # made at the first report, when the total is known

    def progress(done: int, total: int) -> None:
        if not bar:
            bar.append(Progress(total, "grade", True))
        bar[0].update(done)

    t0 = time.perf_counter()
    try:
        board = grade(args.dir, cfg, jobs=args.jobs, scheduler=scheduler, progress=progress,
                      cache=None if getattr(args, "no_cache", False) else out / "cache", secret=secret)
    except (GradeError, ClusterError) as exc:
        raise UsageError(str(exc)) from None
    written = write_outputs(board, out)
    if getattr(args, "gradescope", None):
        try:
            gs = write_gradescope(board.document(), Path(args.gradescope))
        except GradeError as exc:
            raise UsageError(str(exc)) from None
        written.append(Path(args.gradescope))
        print(f"Gradescope: {len(gs)} results.json in {args.gradescope}")
    for r in board.rows:
        score = ("FAILED " + str(r["failed_runs"]) + "/" + str(r["runs"]) if r["failed_runs"]
                 else f"{r['pos_rmse_m']:.4f} m  {r['anees_verdict']}")
        if "rubric_score" in r:
            score = f"{r['rubric_score']:g}/{r['rubric_max']:g} points  " + score
        if r.get("suspicious"):
            score = "SUSPICIOUS (not ranked) " + score
        print(f"{r['rank']:>3}  {r['student']:<20} {score}")
        for flag in r.get("flags", []):
            if not flag.startswith("suspicious"):
                print(f"{'':>5}warning: {flag}")
        for sc, t in r.get("team", {}).items():  # a team scenario: each robot's figures
            robots = ", ".join(f"{rn} {v['pos_rmse_m']:.4f} m" for rn, v in t["robots"].items()
                               if v["pos_rmse_m"] is not None)
            if robots:
                print(f"{'':>5}{sc}: {robots}; team {t['pos_rmse_m']:.4f} m ANEES {t['anees']:.2f}")
        for sc, m in r.get("slam", {}).items():  # a SLAM scenario: the path and the map
            if not r["failed_runs"]:
                print(f"{'':>5}{sc}: ATE {_num(m['ate_m'], '.4f')} m, map GOSPA "
                      f"{_num(m['map_gospa_m'], '.4f')} m, joint NEES {_num(m['joint_nees'], '.2f')}")
    for sc, ref in board.slam_reference.items():
        print(f"reference on {sc} (built-in {ref['filter']}): ATE {_num(ref['ate_m'], '.4f')} m, map GOSPA "
              f"{_num(ref['map_gospa_m'], '.4f')} m, joint NEES {_num(ref['joint_nees'], '.2f')}")
    for sc, ref in board.scan_reference.items():
        print(f"reference on {sc} (built-in {ref['filter']}): {_num(ref['pos_rmse_m'], '.4f')} m")
    for sc, ref in board.reference.items():
        if ref["pos_rmse_m"] is not None:
            print(f"reference on {sc} (built-in independent EKF): team {ref['pos_rmse_m']:.4f} m  "
                  f"ANEES {ref['anees']:.2f}  "
                  + ", ".join(f"{rn} {v['pos_rmse_m']:.4f} m" for rn, v in ref["robots"].items()))
    if board.cached_students:
        print(f"{len(board.cached_students)} student(s) unchanged since the last grade: results "
              f"reused from {out / 'cache'} (--no-cache runs them again)")
    print(f"the students' random streams are keyed by {whence} (fingerprint {board.secret_sha256}), "
          f"kept in {out / SECRET_FILE}: --secret-file it to regrade these figures bit for bit; "
          "do not hand it out")
    print(f"wrote {', '.join(str(p) for p in written)} in {time.perf_counter() - t0:.1f} s "
          f"({'Dask ' + str(scheduler) if scheduler else 'local processes'}; each student's filter "
          f"in its own process, sandbox: {board.sandbox})")
    if board.not_isolated:
        print(board.not_isolated)
    failed = any(r["failed_runs"] for r in board.rows)
    return 1 if failed and args.strict else 0


def _secret(args: argparse.Namespace, out: Path) -> tuple[bytes | None, str]:
    """The grade's secret and how it was chosen: ``--secret-file``; else (without
    ``--new-secret``) the one a grade kept in ``OUT/grade.secret``; else None (a new one)."""
    path = getattr(args, "secret_file", None)
    if path is None and not getattr(args, "new_secret", False) and (out / SECRET_FILE).is_file():
        path = out / SECRET_FILE
    if path is None:
        return None, "a new secret"
    try:
        secret = read_secret(path)
    except GradeError as exc:
        raise UsageError(str(exc)) from None
    given = getattr(args, "secret_file", None) is not None
    return secret, "the secret given (--secret-file)" if given else "the secret of the last grade"


def _num(v: float | None, fmt: str) -> str:
    """A figure, or a dash where there is none."""
    return "-" if v is None else format(v, fmt)
