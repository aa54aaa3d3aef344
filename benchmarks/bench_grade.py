"""Grading a class with each student's filter in a process of its own: a class of
36 files (honest variations of the EKF and the hostile files of tests/attacks and
tests/student_filters), graded locally and on a Dask LocalCluster; every honest student's
figures compared, bit for bit, with grading the honest students alone; and the cost of a
graded run with the isolation against the in-process path of an earlier commit (``--base``:
a folder holding that commit's ``beacon_sim`` and ``scenarios``, e.g. made with
``git archive 62f69b5 beacon_sim scenarios assets | tar -x -C /tmp/base``).

    python benchmarks/bench_grade.py [--seeds 3] [--duration 60] [--base /tmp/base] [--no-dask]
        [--no-class] [--rounds 3] [--sandbox auto]
    python benchmarks/bench_grade.py --team team_sparse [--team-students 8] [--seeds 2]
        [--duration 30] [--rounds 3] [--base /tmp/base]   # a team scenario: this checkout vs --base

Prints FIGURE lines (name, value, unit) and the ratios. The cost (``--base``) is CPU time of
every process (the grader, its workers, the students' children), in interleaved rounds of
the two paths, medians, with the load before and after.
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

from figures import proc_cpu  # noqa: E402

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
    return ("from typing import ClassVar\n\n"
            "from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter\n\n\n"
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
    return {r["student"]: tuple(r[k] for k in FIGURES) for r in board.rows if r["student"] in names}


_MEASURE = """
import json, resource, sys, time
from beacon_sim.evaluation.grading import GradeConfig, grade
def cpu(who):
    u = resource.getrusage(who)
    return u.ru_utime + u.ru_stime
cfg = GradeConfig(**json.loads(sys.argv[2]))
s0, c0, t0 = cpu(resource.RUSAGE_SELF), cpu(resource.RUSAGE_CHILDREN), time.perf_counter()
extra = json.loads(sys.argv[4]) if len(sys.argv) > 4 else {}
board = grade(sys.argv[1], cfg, jobs=json.loads(sys.argv[3]), **extra)
board = board.document() if hasattr(board, "document") else board  # a base checkout: a dict
wall = time.perf_counter() - t0
s1, c1 = cpu(resource.RUSAGE_SELF), cpu(resource.RUSAGE_CHILDREN)
print(json.dumps({"wall": wall, "self": s1 - s0, "children": c1 - c0,
                  "reported": board.get("child_cpu_s", 0.0), "sandbox": board.get("sandbox", "none"),
                  "figures": [[r["student"], r["pos_rmse_m"], r["anees"], r["failed_runs"]]
                              for r in board["rows"]]}))
"""


def measured_grade(path: Path, folder: Path, cfg: dict, jobs: int | None,
                   extra: dict | None = None) -> dict:
    """One grade of ``folder`` by the ``beacon_sim`` in ``path`` (a subprocess): wall [s] and
    CPU [s] of the grader and every process it started. A bubblewrap child is not reaped into
    the grader's resource usage, so there the children's own reports are added. ``extra``:
    more keyword arguments of ``grade``."""
    env = {**os.environ, "PYTHONPATH": str(path), "PYTHONDONTWRITEBYTECODE": "1"}
    out = subprocess.run([sys.executable, "-B", "-c", _MEASURE, str(folder), json.dumps(cfg),
                          json.dumps(jobs), json.dumps(extra or {})], env=env, capture_output=True,
                         text=True, check=True, cwd=tempfile.gettempdir())
    doc = json.loads(out.stdout.strip().splitlines()[-1])
    doc["cpu"] = doc["self"] + doc["children"] + (doc["reported"] if doc["sandbox"] == "bwrap" else 0.0)
    return doc


def median(xs: list[float]) -> float:
    xs = sorted(xs)
    n = len(xs)
    return xs[n // 2] if n % 2 else 0.5 * (xs[n // 2 - 1] + xs[n // 2])


def dask_cpu(args: argparse.Namespace, hon: Path, cfg: GradeConfig, runs: int) -> None:
    """CPU of the same honest class graded on local processes and on a Dask LocalCluster
    (its workers with the children they reaped, and this process, which holds the scheduler,
    the nannies and the client), interleaved rounds, medians. ``--dask-no-profile`` turns
    off Dask's sampling profiler on the workers (``distributed.worker.profile.enabled``)."""
    import resource

    from dask.distributed import Client, LocalCluster

    def self_cpu() -> float:
        u = resource.getrusage(resource.RUSAGE_SELF)
        return u.ru_utime + u.ru_stime

    local_cfg = {"scenarios": list(cfg.scenarios), "seeds": list(cfg.seeds), "duration": cfg.duration,
                 "time_limit": cfg.time_limit, "sandbox": args.sandbox}
    workers = args.jobs or 2
    got: dict[str, list[float]] = {"local": [], "dask": []}
    if args.dask_no_profile:
        import dask

        dask.config.set({"distributed.worker.profile.enabled": False})
    load0 = os.getloadavg()[0]
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        # the workers and, where they are processes of their own, their nannies (a LocalCluster's
        # nannies live in this process, counted by its own resource usage)
        pids = sorted({*client.run(os.getpid).values(), *client.run(os.getppid).values()} - {os.getpid()})
        for _ in range(args.rounds):
            got["local"].append(measured_grade(ROOT, hon, local_cfg, workers)["cpu"])
            c0, s0 = proc_cpu(pids), self_cpu()
            board = grade(hon, GradeConfig(**{**local_cfg, "scenarios": cfg.scenarios, "seeds": cfg.seeds}),
                          scheduler=client)
            extra = board.child_cpu_s if board.sandbox == "bwrap" else 0.0
            got["dask"].append(proc_cpu(pids) - c0 + self_cpu() - s0 + extra)
    local, remote = median(got["local"]), median(got["dask"])
    print(f"FIGURE dask_cpu_load_1min {load0:.2f} -> {os.getloadavg()[0]:.2f}")
    print(f"FIGURE grade_cpu_local {local:.1f} s CPU ({runs} runs, {workers} students at once; median of "
          f"{args.rounds} rounds)")
    print(f"FIGURE grade_cpu_dask {remote:.1f} s CPU (LocalCluster {workers} workers x 1 thread: "
          "workers, nannies, scheduler and client)")
    print(f"FIGURE dask_over_local_cpu {remote / local:.2f} x (target <= 1.10; worker profiler "
          f"{'off' if args.dask_no_profile else 'on'})")
    print("DASK_ROUNDS " + json.dumps(got))


def cost(args: argparse.Namespace, hon: Path, runs: int) -> None:
    """The cost of a graded run: the honest class graded isolated (this checkout) and in
    process (the base commit, each run simulating its own truth), interleaved rounds,
    medians; CPU of every process, wall time beside it."""
    base_cfg = {"scenarios": ["default"], "seeds": list(range(args.seeds)), "duration": args.duration,
                "time_limit": args.time_limit}
    iso_cfg = {**base_cfg, "sandbox": args.sandbox}
    if args.sandbox == "process":  # a class there is graded only on the teacher's word
        iso_cfg["allow_unisolated"] = True
    load0 = os.getloadavg()[0]
    got: dict[str, list[dict]] = {"iso": [], "base": []}
    for _ in range(args.rounds):
        got["iso"].append(measured_grade(ROOT, hon, iso_cfg, args.jobs))
        got["base"].append(measured_grade(args.base, hon, base_cfg, args.jobs))
    load1 = os.getloadavg()[0]
    iso_cpu, base_cpu = median([g["cpu"] for g in got["iso"]]), median([g["cpu"] for g in got["base"]])
    iso_wall, base_wall = median([g["wall"] for g in got["iso"]]), median([g["wall"] for g in got["base"]])
    sandbox = got["iso"][0]["sandbox"]
    print(f"FIGURE load_1min {load0:.2f} -> {load1:.2f} (before and after the {args.rounds} rounds)")
    print(f"FIGURE graded_run_cpu_isolated {iso_cpu / runs * 1e3:.1f} ms CPU per run ({runs} runs, sandbox "
          f"{sandbox}; simulation once per seed, child start, probes and scoring included; median of "
          f"{args.rounds} rounds)")
    print(f"FIGURE graded_run_cpu_in_process_base {base_cpu / runs * 1e3:.1f} ms CPU per run (the base "
          "commit's grade, each run simulating its own truth)")
    print(f"FIGURE class_runs_per_cpu_s {runs / iso_cpu:.1f} isolated, {runs / base_cpu:.1f} in process")
    print(f"FIGURE isolated_over_in_process_cpu {iso_cpu / base_cpu:.2f} x (target <= 1.5: a sandboxed, "
          "limited child per student against grading in this process)")
    print(f"FIGURE isolated_over_in_process_wall {iso_wall / base_wall:.2f} x (jobs: "
          f"{args.jobs or 'each default'}; {iso_wall:.1f} s against {base_wall:.1f} s)")
    print("ROUNDS " + json.dumps(got))


def team_cost(args: argparse.Namespace, hon: Path, students: int) -> None:
    """A team scenario graded (each (scenario, seed) simulated once, each robot's ticks
    streamed to the students' children) by this checkout against the checkout in
    ``--base`` (default: this one), the same class, interleaved rounds, medians of the CPU
    of every process."""
    cfg = {"scenarios": [args.team], "seeds": list(range(args.seeds)), "duration": args.duration,
           "time_limit": args.time_limit, "sandbox": args.sandbox}
    runs = students * args.seeds
    base = args.base or ROOT
    load0 = os.getloadavg()[0]
    got: dict[str, list[dict]] = {"this": [], "base": []}
    for _ in range(args.rounds):
        got["base"].append(measured_grade(base, hon, cfg, args.jobs))
        got["this"].append(measured_grade(ROOT, hon, cfg, args.jobs))
    load1 = os.getloadavg()[0]
    this, before = median([g["cpu"] for g in got["this"]]), median([g["cpu"] for g in got["base"]])
    w_this, w_before = median([g["wall"] for g in got["this"]]), median([g["wall"] for g in got["base"]])
    same = all(g["figures"] == got["base"][0]["figures"] for g in got["this"] + got["base"])
    print(f"FIGURE team_load_1min {load0:.2f} -> {load1:.2f} (before and after the {args.rounds} rounds)")
    print(f"FIGURE team_runs_per_cpu_s {runs / before:.2f} base, {runs / this:.2f} this checkout "
          f"({students} students x {args.seeds} seeds of {args.team}, {args.duration:g} s; sandbox "
          f"{got['this'][0]['sandbox']}; medians of {args.rounds} rounds)")
    print(f"FIGURE team_this_over_base_cpu {this / before:.2f} x ({this:.1f} s against {before:.1f} s CPU)")
    print(f"FIGURE team_this_over_base_wall {w_this / w_before:.2f} x ({w_this:.1f} s against "
          f"{w_before:.1f} s)")
    print(f"FIGURE team_figures_identical {same}")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--time-limit", type=float, default=10.0)
    ap.add_argument("--jobs", type=int, default=None,
                    help="students at once (default: each grade's own default)")
    ap.add_argument("--base", type=Path)
    ap.add_argument("--no-dask", action="store_true")
    ap.add_argument("--no-class", action="store_true",
                    help="skip the 36-file class (only the cost, with --base)")
    ap.add_argument("--rounds", type=int, default=3, help="interleaved rounds of the cost")
    ap.add_argument("--sandbox", default="auto", help="the isolated grade's level (auto, bwrap, process)")
    ap.add_argument("--dask-cpu", action="store_true",
                    help="CPU of the honest class on local processes against a Dask LocalCluster")
    ap.add_argument("--dask-no-profile", action="store_true",
                    help="with --dask-cpu: Dask's sampling profiler off on the workers")
    ap.add_argument("--team", default=None, metavar="SCENARIO",
                    help="only the team cost: this team scenario graded by this checkout against "
                         "--base's, on --team-students honest files")
    ap.add_argument("--team-students", type=int, default=8)
    args = ap.parse_args()
    if args.team:
        tmp = Path(tempfile.mkdtemp(prefix="bench-grade-team-"))
        names = write_class(tmp / "alone", max(1, args.team_students - 3), hostile=False)
        team_cost(args, tmp / "alone", len(names))
        shutil.rmtree(tmp, ignore_errors=True)
        return
    cfg = GradeConfig(scenarios=("default",), seeds=tuple(range(args.seeds)), duration=args.duration,
                      time_limit=args.time_limit)
    tmp = Path(tempfile.mkdtemp(prefix="bench-grade-"))
    klass = tmp / "class"
    honest = write_class(klass, 21, hostile=True)
    if args.no_class:
        write_class(tmp / "alone", 21, hostile=False)
        if args.base is not None:
            cost(args, tmp / "alone", len(honest) * args.seeds)
        if args.dask_cpu:
            dask_cpu(args, tmp / "alone", cfg, len(honest) * args.seeds)
        shutil.rmtree(tmp, ignore_errors=True)
        return
    n = len(list(klass.glob("*.py")))
    print(f"FIGURE class_files {n} files ({len(honest)} honest)")

    t0 = time.perf_counter()
    board = grade(klass, cfg, jobs=args.jobs)
    local_s = time.perf_counter() - t0
    print(f"FIGURE grade_local_wall {local_s:.1f} s (sandbox {board.sandbox}, jobs "
          f"{args.jobs or 'default'}, {args.seeds} seeds x {args.duration:g} s)")
    write_class(tmp / "alone", 21, hostile=False)
    alone = grade(tmp / "alone", cfg, jobs=args.jobs)
    same = figures(board, honest) == figures(alone, honest)
    print(f"FIGURE honest_identical_to_alone_local {same} ({len(honest)} students)")
    print("ROWS " + json.dumps([(r["rank"], r["student"], r["pos_rmse_m"], r.get("suspicious"),
                                 [f["reason"] for f in r["failures"][:1]], r.get("flags"))
                                for r in board.rows], default=str))

    if not args.no_dask:
        from dask.distributed import Client, LocalCluster

        with LocalCluster(n_workers=args.jobs or 2, threads_per_worker=1, processes=True,
                          dashboard_address=None) as cluster, Client(cluster) as client:
            t0 = time.perf_counter()
            remote = grade(klass, cfg, scheduler=client)
            dask_s = time.perf_counter() - t0
        print(f"FIGURE grade_dask_wall {dask_s:.1f} s (LocalCluster {args.jobs or 2} workers x 1 thread)")
        print(f"FIGURE honest_identical_to_alone_dask {figures(remote, honest) == figures(alone, honest)}")
        everyone = [r["student"] for r in board.rows]
        print(f"FIGURE dask_identical_to_local {figures(remote, everyone) == figures(board, everyone)}")

    if args.base is not None:  # the cost of a graded run: the honest class, isolated vs in process
        if not (tmp / "alone").exists():
            write_class(tmp / "alone", 21, hostile=False)
        cost(args, tmp / "alone", len(honest) * args.seeds)
    shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
