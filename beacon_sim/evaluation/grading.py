"""Grading a class (``beacon-sim grade DIR``, docs/grading.md): every student's filter file
over the same scenarios and seeds, one row per student, a CSV and a self-contained HTML
leaderboard.

The sweep is a list of independent tasks (student, scenario, seed), each a
:func:`~beacon_sim.evaluation.montecarlo.one_run` with a per-run time limit, so it runs the
same on local processes (default) and on a Dask distributed cluster (``scheduler``): a
run's numbers depend only on its seed, never on where it ran (only the cost figures, wall
time, differ). A task that cannot run (the file does not import, a worker died of memory)
is a failed run, not a failed sweep. A student whose filter failed in any run gets no
score and is ranked below every working filter.

A team scenario (``[[robots]]``, docs/multi-robot.md) among the scenarios grades the
student's single-robot filter as every robot's own filter (``independent:FILTER``, the
team baseline: beacon readings only), beside the built-in independent EKF on the same
seeds (the ``reference``): the row's figures for it are the team's (RMSE over all robots,
mean ANEES, RMSE over each robot's bound alone), and ``team`` holds each robot's.

A SLAM scenario (the beacon map withheld) adds the map columns (the path's ATE, the final
map's GOSPA, the joint NEES) beside the built-in EKF-SLAM; a map world with a range finder
puts each row beside the built-in mcl (docs/grading.md, "A SLAM assignment", "A scan-based
assignment").
"""

from __future__ import annotations

import ast
import csv
import dataclasses
import html
import json
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from beacon_sim.core.arguments import check_simulated_total
from beacon_sim.core.files import (
    MAX_SOURCE_BYTES,
    atomic_write,
    read_user_bytes,
    read_user_text,
    write_text_atomic,
)
from beacon_sim.core.scenario import Scenario, load_scenario, read_user_toml
from beacon_sim.core.team_scenario import TeamScenario, is_team_scenario, load_team_scenario
from beacon_sim.errors import BeaconSimError
from beacon_sim.evaluation.montecarlo import (
    RunOutput,
    SimulatedRun,
    TeamRunOutput,
    default_jobs,
    init_worker,
    isolated_run,
    isolated_runs,
    on_dask,
    one_run,
    simulate_run,
    team_one_run,
)
from beacon_sim.evaluation.slam_metrics import ate, gospa
from beacon_sim.evaluation.slam_run import GOSPA_CUTOFF_M, joint_nees_at, mapped_beacons
from beacon_sim.evaluation.summary import Thresholds, evaluate, evaluate_team, overall_verdict
from beacon_sim.hosting.client import ChildSession, FilterChild, step_request
from beacon_sim.hosting.containment import SANDBOXES, Limits, SandboxError, resolve_sandbox
from beacon_sim.hosting.feed import LOG_BYTES as FEED_LOG_BYTES
from beacon_sim.hosting.feed import PROBE_TICKS as FEED_PROBE_TICKS
from beacon_sim.hosting.feed import PROBES, ProbeFindings, child_limits, reply_timeout
from beacon_sim.hosting.loading import FILTER_METHODS, FUNCTIONS
from beacon_sim.hosting.runner import SLOW_STEP_MS
from beacon_sim.hosting.team_specs import MEMBER_PREFIX

#: The student name of the built-in filter graded beside the students on team scenarios.
REFERENCE = "__reference__"
#: Its spec: every robot's own built-in EKF (the ``independent`` team filter).
REFERENCE_SPEC = "ekf"
#: The built-in filter graded beside the students on a SLAM scenario (``[model] map =
#: "unknown"``), in the grader's process on the same simulated runs: the map's reference.
SLAM_REFERENCE_SPEC = "ekf_slam"
#: A SLAM row's figures (docs/grading.md, "A SLAM assignment"): the path's ATE [m], the
#: final map's GOSPA [m] (cut-off ``GOSPA_CUTOFF_M``, as ``run``), its landmarks, missed
#: and false ones, and the final joint NEES (where the filter has ``joint()``), seed means.
#: The built-in filter graded beside the students on a map world with a range finder (a
#: scan-based assignment, docs/maps.md): in the grader's process, on the same seeds.
SCAN_REFERENCE_SPEC = "mcl"
SLAM_FIGURES = ("ate_m", "map_gospa_m", "map_landmarks", "map_missed", "map_false", "joint_nees")


class GradeError(BeaconSimError):
    """A bad grading folder or configuration file (one line, exit status 2)."""


@dataclass(frozen=True)
class GradeConfig:
    """What the class is graded on (a ``grade.toml`` may set any of these).

    scenarios : shipped names or TOML paths (default: ``default``).
    seeds : the run seeds, the same for every student (default 0 to 4).
    duration : seconds per run [s] (default 60; None: each scenario's own).
    time_limit : a filter's time limit per run [s] (default 60).
    memory_limit_gb : each student's child process's address-space limit [GB] (default 4;
        0: none), on local processes and Dask workers alike.
    class_name : the filter class in each file (default: found in the file).
    sandbox : ``auto``, ``bwrap`` or ``process`` (docs/grading.md, "What grading protects
        against"); ``auto``: bubblewrap where it works, else the process level.
    pseudonyms : the class page (grade.html) names students by a pseudonym; the teacher's
        files (grade.csv, grade.json, pseudonyms.csv) keep the real names.
    """

    scenarios: tuple[str, ...] = ("default",)
    seeds: tuple[int, ...] = (0, 1, 2, 3, 4)
    duration: float | None = 60.0
    time_limit: float = 60.0
    memory_limit_gb: float = 4.0
    class_name: str | None = None
    sandbox: str = "auto"
    pseudonyms: bool = False


#: The longest run a grading configuration may ask for [s] (one simulated day).
MAX_GRADE_DURATION_S = 86400.0
#: The largest grade config read [bytes].
MAX_CONFIG_BYTES = 2**20


def _config_list(path: str | Path, data: dict[str, Any], key: str, kind: type, what: str,
                 default: tuple[Any, ...]) -> tuple[Any, ...]:
    """``key`` as a non-empty list (at most 10,000 entries) of ``kind`` values."""
    if key not in data:
        return default
    value = data[key]
    ok = isinstance(value, list) and 1 <= len(value) <= 10_000 and all(
        isinstance(v, kind) and not isinstance(v, bool) for v in value)
    if ok and kind is int:
        ok = all(0 <= v <= 2**63 - 1 for v in value)
    if ok and kind is str:
        ok = all(v.strip() for v in value)
    if not ok:
        raise GradeError(f"{path}: {key} = {value!r}: expected a list of 1 to 10000 {what}")
    return tuple(value)


def _config_number(path: str | Path, data: dict[str, Any], key: str, default: float, *, hi: float,
                   zero_is_none: bool = False, allow_zero: bool = False) -> Any:
    """``key`` as a finite number in (0, hi] ([0, hi] with ``allow_zero``; 0 means None with
    ``zero_is_none``)."""
    if key not in data:
        return default
    value = data[key]
    ok = isinstance(value, int | float) and not isinstance(value, bool)
    if ok:
        try:
            x = float(value)
        except OverflowError:
            ok = False
    if ok and x == 0.0 and (zero_is_none or allow_zero):
        return None if zero_is_none else 0.0
    if not ok or not (math.isfinite(x) and 0.0 < x <= hi):
        low = "[0" if (zero_is_none or allow_zero) else "(0"
        extra = " (0: each scenario's own)" if zero_is_none else ""
        raise GradeError(f"{path}: {key} = {value!r}: expected a number in {low}, {hi:g}]{extra}")
    return x


def _config_name(path: str | Path, data: dict[str, Any]) -> str | None:
    value = data.get("class_name")
    if value is not None and not (isinstance(value, str) and value.isidentifier()):
        raise GradeError(f"{path}: class_name = {value!r}: expected a Python class name")
    return value


def load_config(path: str | Path | None) -> GradeConfig:
    """A :class:`GradeConfig` from a TOML file (keys as the attributes), or the defaults."""
    if path is None:
        return GradeConfig()
    data = read_user_toml(path, what="grade config", cap=MAX_CONFIG_BYTES, error=GradeError)
    known = set(GradeConfig.__dataclass_fields__)
    unknown = sorted(set(data) - known)
    if unknown:
        raise GradeError(f"{path}: unknown key(s) {', '.join(unknown)}; known: {', '.join(sorted(known))}")
    cfg = GradeConfig(
        scenarios=_config_list(path, data, "scenarios", str, "names or paths (strings)",
                               GradeConfig.scenarios),
        seeds=_config_list(path, data, "seeds", int, "integer seeds in [0, 2^63 - 1], e.g. [0, 1, 2]",
                           GradeConfig.seeds),
        duration=_config_number(path, data, "duration", 60.0, hi=MAX_GRADE_DURATION_S, zero_is_none=True),
        time_limit=_config_number(path, data, "time_limit", GradeConfig.time_limit, hi=86400.0),
        memory_limit_gb=_config_number(path, data, "memory_limit_gb", GradeConfig.memory_limit_gb,
                                       hi=1e4, allow_zero=True),
        class_name=_config_name(path, data),
        sandbox=_config_sandbox(path, data),
        pseudonyms=_config_bool(path, data, "pseudonyms"))
    if cfg.duration is not None:
        check_simulated_total(len(cfg.seeds) * len(cfg.scenarios), cfg.duration,
                              f"{path}: seeds x scenarios x duration", GradeError)
    return cfg


def _config_bool(path: str | Path, data: dict[str, Any], key: str) -> bool:
    value = data.get(key, False)
    if not isinstance(value, bool):
        raise GradeError(f"{path}: {key} = {value!r}: expected true or false")
    return value


def _config_sandbox(path: str | Path, data: dict[str, Any]) -> str:
    value = data.get("sandbox", "auto")
    if value not in SANDBOXES:
        raise GradeError(f"{path}: sandbox = {value!r}: expected one of {', '.join(SANDBOXES)}")
    return str(value)


@dataclass(frozen=True)
class Student:
    """One file: the student (the file's stem), the filter spec, or why it has none."""

    name: str
    path: Path
    spec: str | None
    problem: str | None = None
    class_name: str | None = None


def find_class(path: Path, class_name: str | None = None) -> str | None:
    """The filter class of a student's file, read without running it (``ast``): the one
    named ``class_name``; else the last top-level class defining all of reset, predict,
    update and estimate; else None (the class that implements the interface, perhaps by
    inheritance, or the file's module-level functions: chosen in the student's own child
    process, :func:`~beacon_sim.hosting.loading.choose_filter`). Raises GradeError (syntax
    error, no such class)."""
    text = read_user_text(path, what="filter file", cap=MAX_SOURCE_BYTES, error=GradeError)
    try:
        tree = ast.parse(text, str(path))
    except (SyntaxError, UnicodeDecodeError, OSError, ValueError) as exc:
        raise GradeError(f"does not import: {type(exc).__name__}: {exc}") from None
    classes = [n for n in tree.body if isinstance(n, ast.ClassDef)]
    if class_name is not None:
        if any(c.name == class_name for c in classes) or class_name == FUNCTIONS:
            return class_name
        raise GradeError(f"no class {class_name!r}")
    full = [c for c in classes if {f.name for f in c.body if isinstance(f, ast.FunctionDef)}
            >= set(FILTER_METHODS)]
    return full[-1].name if full else None


def find_students(folder: str | Path, class_name: str | None = None) -> list[Student]:
    """Every ``*.py`` file of ``folder`` (sorted, ``_``-prefixed files left out)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise GradeError(f"{folder}: not a folder")
    out = []
    for path in sorted(folder.glob("*.py")):
        if path.name.startswith("_"):
            continue
        try:
            cls = find_class(path, class_name)
        except GradeError as exc:
            out.append(Student(path.stem, path, None, str(exc)))
            continue
        out.append(Student(path.stem, path, f"{path.resolve()}:{cls}" if cls else str(path.resolve()),
                           class_name=cls))
    if not out:
        raise GradeError(f"{folder}: no filter files (*.py)")
    return out


@dataclass(frozen=True)
class Task:
    """One run of one student's filter: picklable, so it runs in any worker."""

    student: str
    spec: str
    scenario: str
    seed: int
    duration: float | None
    time_limit: float
    index: int
    #: The key of the filter's random streams (the grade's secret; None: the public key).
    secret: bytes | None = dataclasses.field(default=None, repr=False)


@dataclass
class TaskResult:
    """A task's run, or why it could not run at all."""

    task: Task
    run: RunOutput | TeamRunOutput | None
    problem: str | None = None
    wall_s: float = 0.0
    report: dict[str, Any] | None = None  # what the student's child said of the run


def run_task(task: Task) -> TaskResult:
    """Run one task (in whatever process or thread a worker gives it)."""
    t0 = time.perf_counter()
    try:
        if is_team_scenario(task.scenario):  # the student's filter as every robot's own
            team = load_team_scenario(task.scenario)
            duration = team.duration if task.duration is None else task.duration
            trun = team_one_run(team, [MEMBER_PREFIX + task.spec], {}, task.seed, duration,
                                index=task.index, step_limit_s=task.time_limit,
                                run_limit_s=task.time_limit, secret=task.secret)
            return TaskResult(task, trun, None, time.perf_counter() - t0)
        sc = load_scenario(task.scenario)
        duration = sc.duration if task.duration is None else task.duration
        run = one_run(sc, [task.spec], {}, task.seed, duration, index=task.index,
                      keep_means=task.index == 0, run_limit_s=task.time_limit, secret=task.secret)
        return TaskResult(task, run, None, time.perf_counter() - t0)
    except MemoryError:
        return TaskResult(task, None, "out of memory", time.perf_counter() - t0)
    except Exception as exc:  # the file does not import, the class cannot be built...
        text = str(exc).strip().splitlines()
        why = text[0] if text else type(exc).__name__
        return TaskResult(task, None, f"{type(exc).__name__}: {why}" if not isinstance(exc, ValueError)
                          else why, time.perf_counter() - t0)


def run_tasks(tasks: Sequence[Task], jobs: int | None = None, scheduler: Any = None,
              memory_limit_gb: float = 4.0,
              progress: Callable[[int, int], None] | None = None) -> list[TaskResult]:
    """Run every task; results in task order.

    ``scheduler``: None runs on ``jobs`` local processes (default: all cores); an address
    (``tcp://host:8786``) or a ``dask.distributed`` Client / cluster runs on Dask. A task
    whose worker died (memory) is a failed run with that reason.
    """
    out: list[TaskResult | None] = [None] * len(tasks)
    done = 0

    def finish(i: int, res: TaskResult) -> None:
        nonlocal done
        out[i] = res
        done += 1
        if progress:
            progress(done, len(tasks))

    if scheduler is not None:
        on_dask(scheduler, run_task, list(tasks), finish,  # KilledWorker: the filter took it down
                lost=lambda i, exc: finish(i, TaskResult(tasks[i], None,
                                                         f"worker lost: {type(exc).__name__}")))
        return [r for r in out if r is not None]
    jobs = default_jobs() if jobs is None else max(1, int(jobs))
    from concurrent.futures import ProcessPoolExecutor
    from concurrent.futures.process import BrokenProcessPool

    pending = list(range(len(tasks)))
    while pending:  # a pool broken by a dead worker is replaced; its task is failed
        broken = False
        with ProcessPoolExecutor(max_workers=min(jobs, len(pending)), initializer=init_worker,
                                 initargs=(memory_limit_gb,)) as pool:
            futs = {pool.submit(run_task, tasks[i]): i for i in pending}
            for fut, i in futs.items():
                try:
                    finish(i, fut.result())
                except BrokenProcessPool:
                    broken = True
                    break
        if not broken:
            break
        left = [i for i in pending if out[i] is None]
        finish(left[0], TaskResult(tasks[left[0]], None, "worker died (memory?)"))
        pending = left[1:]
    return [r for r in out if r is not None]


#: How many ticks the probes of a student's filter run (the first scenario and seed; see
#: :mod:`beacon_sim.hosting.feed`): the run fed again (is it deterministic?), the run with
#: its readings drawn again (does it use them?) and that fed again. LOG_BYTES: the most of
#: a student's log the leaderboard keeps and links [bytes].
PROBE_TICKS = FEED_PROBE_TICKS
LOG_BYTES = FEED_LOG_BYTES


@dataclass
class TeamSimulated:
    """One team (scenario, seed) simulated once by the grader (issue 27): each robot's run
    as a :class:`~beacon_sim.evaluation.montecarlo.SimulatedRun` (its command, dt and beacon
    readings per tick, what that robot's copy of a student's filter is fed; its truth stays
    here) and the team's arrays for the scoring."""

    label: str
    index: int
    seed: int
    robots: list[SimulatedRun]
    robot_ids: list[str]
    robot_names: list[str]
    truth: np.ndarray  # (T + 1, N, 3), row 0 the start
    controls: np.ndarray  # (T, N, 2)
    kidnapped: np.ndarray  # (T, N)
    truth_checksum: str


def simulate_team_run(team: TeamScenario, seed: int, duration: float, index: int = 0,
                      label: str | None = None, secret: bytes | None = None) -> TeamSimulated:
    """Simulate one team run as ``run_headless`` does (the same truth), without filters:
    per robot the "step" requests its copy of a single-robot filter gets (the team
    baseline: that robot's beacon readings), pickled once for every student. ``secret``:
    the key of the filters' streams (None: the public key)."""
    from beacon_sim.core.streams import run_key
    from beacon_sim.core.team import TeamSimulation

    sim = TeamSimulation(team, seed)
    T, N = round(duration / team.dt), team.n_robots
    truth = np.empty((T + 1, N, 3))
    truth[0] = [r.scenario.initial_pose for r in team.robots]
    controls = np.empty((T, N, 2))
    kidnapped = np.zeros((T, N), dtype=bool)
    frames: list[list[bytes]] = [[] for _ in range(N)]
    for k in range(T):
        step = sim.step()
        for i, st in enumerate(step.steps):
            truth[k + 1, i] = st.true_pose
            controls[k, i] = (st.control.v, st.control.omega)
            kidnapped[k, i] = st.kidnapped
            frames[i].append(step_request(st.control, st.dt, st.measurements, False))
    label = team.name if label is None else label
    checksum = sim.truth_checksum
    robots = [SimulatedRun(r.scenario, index, seed, truth[:, i].copy(), controls[:, i].copy(),
                           kidnapped[:, i].copy(), checksum, [], np.zeros(T, dtype=int), frames[i], None,
                           label, run_key(seed, secret)) for i, r in enumerate(team.robots)]
    return TeamSimulated(label, index, seed, robots, [str(r.id) for r in team.robots],
                         [str(r.name) for r in team.robots], truth, controls, kidnapped, checksum)


def team_output(ts: TeamSimulated, runs: list[RunOutput], name: str) -> TeamRunOutput:
    """The team run of a student's filter from its robots' runs (one per robot, fed
    together): as the grader's in-worker team run scores it. A copy that failed on one
    robot fails the filter on every robot from that tick ("robot NAME: why"), the rows
    after it NaN; the cost is the sum over the robots."""
    T = len(ts.robots[0].frames)
    frs = [next(iter(r.filters.values())) for r in runs]

    def first_bad(fr: Any) -> int:
        bad = ~np.isfinite(fr.err[:, 0])
        return int(np.argmax(bad)) if bad.any() else T

    ends = [first_bad(fr) if fr.failed else min(first_bad(fr), fr.steps) for fr in frs]
    n_ok = min(ends)
    failing = [i for i, fr in enumerate(frs) if fr.failed]
    why = None
    if failing:
        i = min(failing, key=lambda j: (ends[j], j))
        why = f"robot {ts.robot_names[i]}: {frs[i].failed}"
    step_ns = int(sum(fr.step_ns for fr in frs))
    out = TeamRunOutput(ts.index, ts.seed, ts.truth, ts.controls, ts.kidnapped, ts.truth_checksum)
    copies = []
    for fr in frs:
        err, var, nees = fr.err.copy(), fr.var.copy(), fr.nees.copy()
        means = None if fr.means is None else fr.means.copy()
        for a in (err, var, nees) + ((means,) if means is not None else ()):
            a[n_ok:] = np.nan
        copies.append(dataclasses.replace(fr, err=err, var=var, nees=nees, means=means, nis_sum=0.0,
                                          nis_dof=0, step_ns=step_ns, steps=n_ok if why else fr.steps,
                                          failed=why, landmarks=None, joint=None))
    out.filters[name] = copies
    return out


@dataclass
class StudentJob:
    """Everything one student's runs need, picklable (a Dask task): the file's bytes (not
    its path: a worker needs no shared file system), the simulated runs (scenario, seed)
    in task order, and the grading settings."""

    student: str
    filename: str
    source: bytes
    class_name: str | None
    sims: list[SimulatedRun]
    time_limit: float
    memory_limit_gb: float
    sandbox: str
    team_sims: list[TeamSimulated] = dataclasses.field(default_factory=list)  # team scenarios


@dataclass
class StudentResult:
    """One student's runs (task order), the findings of the probes and the child's log."""

    student: str
    results: list[TaskResult]
    findings: dict[str, Any]
    log: str
    sandbox: str


def _limits(job: StudentJob) -> Limits:
    runs = len(job.sims) + len(PROBES) + sum(len(ts.robots) for ts in job.team_sims)
    return child_limits(job.time_limit, runs, job.memory_limit_gb)


def _batches(sims: list[SimulatedRun]) -> list[list[int]]:
    """The runs of a student fed together (one exchange per tick): consecutive runs of the
    same scenario and length (a scenario's seeds), as indices into ``sims``."""
    out: list[list[int]] = []
    for k, sr in enumerate(sims):
        if out and sims[out[-1][0]].label == sr.label and len(sims[out[-1][0]].frames) == len(sr.frames):
            out[-1].append(k)
        else:
            out.append([k])
    return out


def run_student(job: StudentJob) -> StudentResult:
    """Every run of one student's filter in a child process of its own, on the simulations
    the grader made; the scoring stays here. A scenario's seeds are fed together
    (:func:`~beacon_sim.evaluation.montecarlo.isolated_runs`: one filter per seed in the
    child, one exchange per tick for all of them); a filter that draws from the global
    generators is run again one seed at a time in a fresh child (its figures then depend
    on its own seed alone, as the global generators are seeded per run). A fresh child
    follows a batch that killed or broke one. Then the two probes (see :data:`PROBE_TICKS`).
    Never raises for the filter's sake."""
    import tempfile

    t_start = time.perf_counter()
    findings: dict[str, Any] = {"global_rng": False, "heading_wrapped": True, "deterministic": None,
                                "readings_used": None, "form": None, "child_cpu_s": 0.0,
                                "probe_failures": []}
    results: list[TaskResult | None] = [None] * len(job.sims)
    with tempfile.TemporaryDirectory(prefix="beacon-sim-grade-") as tmp:
        src = Path(tmp) / job.filename
        src.write_bytes(job.source)
        log = Path(tmp) / "log.txt"
        session = ChildSession(src, job.class_name, log, job.sandbox, _limits(job),
                               reply_timeout(job.time_limit))
        load_problem: str | None = None

        def task(sr: SimulatedRun) -> Task:
            return Task(job.student, job.filename, sr.label, sr.seed, None, job.time_limit, sr.index)

        def started() -> FilterChild | None:
            nonlocal load_problem
            child = session.child()
            if child is not None:
                findings["form"] = session.form
            elif load_problem is None:
                load_problem = findings["load_problem"] = session.load_problem
            return child

        def stop() -> None:
            session.stop()
            findings["child_cpu_s"] = session.cpu_s

        def record(k: int, run: RunOutput, rep: dict[str, Any], wall_s: float) -> None:
            if rep.get("heading_unwrapped"):
                findings["heading_wrapped"] = False
            results[k] = TaskResult(task(job.sims[k]), run, None, wall_s,
                                    {k2: v for k2, v in rep.items() if k2 not in ("means", "probes")})

        team_results: list[TaskResult] = []
        try:
            for batch in _batches(job.sims):
                t0 = time.perf_counter()
                child = started()
                if child is None:
                    for k in batch:
                        results[k] = TaskResult(task(job.sims[k]), None, load_problem, 0.0)
                    continue
                probing = batch[0] == 0  # the probes ride along in the first batch
                runs, rep = isolated_runs(child, [job.sims[k] for k in batch], job.time_limit,
                                          probe_ticks=PROBE_TICKS if probing else None)
                if rep.get("failed_child"):
                    stop()
                if rep.get("np_global") or rep.get("py_global"):
                    findings["global_rng"] = True
                    stop()  # its seeds shared the global stream: each run alone, afresh
                    for k in batch:
                        t1 = time.perf_counter()
                        one = started()
                        if one is None:
                            results[k] = TaskResult(task(job.sims[k]), None, load_problem, 0.0)
                            continue
                        run, rep1 = isolated_run(one, job.sims[k], job.time_limit,
                                                 keep_means=job.sims[k].index == 0)
                        if rep1.get("failed_child"):
                            stop()
                        record(k, run, rep1, time.perf_counter() - t1)
                    first = results[0]
                    again = started() if probing and first is not None and first.run is not None else None
                    if again is not None and first is not None:
                        if not _probe(again, job.sims[0], job, findings, first):
                            stop()
                else:
                    wall = (time.perf_counter() - t0) / len(batch)
                    for k, run in zip(batch, runs, strict=True):
                        record(k, run, rep, wall)
                    if probing:
                        _probe_findings(job.sims[0], rep.get("probes") or ProbeFindings(), findings)
            team_results += _run_team_batches(job, started, stop, record_team=findings)
        finally:
            stop()
        raw = log.read_bytes() if log.exists() else b""
        text = raw[:LOG_BYTES + 100].decode("utf-8", "replace")
        if len(raw) > LOG_BYTES + 100:
            text += f"\n[log cut at {LOG_BYTES} bytes]\n"
    findings["wall_s"] = time.perf_counter() - t_start
    return StudentResult(job.student, [r for r in results if r is not None] + team_results, findings, text,
                         job.sandbox)


def _run_team_batches(job: StudentJob, started: Callable[[], FilterChild | None],
                      stop: Callable[[], None], record_team: dict[str, Any]) -> list[TaskResult]:
    """The student's team runs (issue 27): per team scenario, every robot of every seed fed
    together in the student's child (one filter per robot and seed, one exchange per tick),
    on the runs the grader simulated once; each robot's copy named ``CLASS/ROBOT_ID`` (its
    own random stream), with the scenario's ``[filters.CLASS]``. A filter that draws from
    the global generators is run again robot by robot, afresh, as on single-robot runs."""
    out: list[TaskResult] = []
    groups: dict[str, list[TeamSimulated]] = {}
    for ts in job.team_sims:
        groups.setdefault(ts.label, []).append(ts)
    for group in groups.values():
        t0 = time.perf_counter()

        def task(ts: TeamSimulated) -> Task:
            return Task(job.student, job.filename, ts.label, ts.seed, None, job.time_limit, ts.index)

        child = started()
        if child is None:
            why = record_team.get("load_problem") or "the filter's file could not be loaded"
            out += [TaskResult(task(ts), None, why, 0.0) for ts in group]
            continue
        cls = child.class_name
        sims = [r for ts in group for r in ts.robots]
        names = [f"{cls}/{rid}" for ts in group for rid in ts.robot_ids]
        params = [dict(r.scenario.filter_params.get(cls, {})) for r in sims]
        runs, rep = isolated_runs(child, sims, job.time_limit, name=names, params=params)
        if rep.get("failed_child"):
            stop()
        if rep.get("heading_unwrapped"):
            record_team["heading_wrapped"] = False
        if rep.get("np_global") or rep.get("py_global"):
            record_team["global_rng"] = True
            stop()
            runs = []
            for sr, nm, pr in zip(sims, names, params, strict=True):
                one = started()
                if one is None:  # it loaded once: a file that no longer loads fails these runs
                    break
                run, rep1 = isolated_run(one, sr, job.time_limit, keep_means=sr.index == 0, name=nm,
                                         params=pr)
                if rep1.get("failed_child"):
                    stop()
                runs.append(run)
            if len(runs) < len(sims):
                why = record_team.get("load_problem") or "the filter's file could not be loaded again"
                out += [TaskResult(task(ts), None, why, 0.0) for ts in group]
                continue
        wall = (time.perf_counter() - t0) / len(group)
        at = 0
        for ts in group:
            n = len(ts.robots)
            out.append(TaskResult(task(ts), team_output(ts, runs[at:at + n], cls), None, wall))
            at += n
    return out


def run_student_shared(job: StudentJob, shared: tuple[list[SimulatedRun], list[TeamSimulated]]
                       ) -> StudentResult:
    """:func:`run_student` of a job sent without its runs, on the runs every worker got once
    (a Dask task of :func:`run_students`): the single-robot runs and the team runs."""
    return run_student(dataclasses.replace(job, sims=shared[0], team_sims=shared[1]))


def _probe_findings(sr: SimulatedRun, probes: ProbeFindings, findings: dict[str, Any]) -> None:
    """``deterministic``, ``readings_used`` and the probes a filter failed on its own
    (``probe_failures``: a probe is one more run, and failing it is failing a run) from the
    probes that rode in the first batch (:func:`~beacon_sim.hosting.feed.judge_probes`)."""
    findings["deterministic"] = probes.deterministic
    findings["readings_used"] = probes.readings_used
    findings["probe_failures"] = [
        {"scenario": sr.label, "seed": sr.seed, "time_s": (at + 1) * sr.scenario.dt,
         "reason": f"probe ({PROBE_WORDS[name]}): {why}"} for name, (why, at) in probes.failures.items()]


#: How a probe is named where its failure is shown.
PROBE_WORDS = {"again": "the first run fed again", "extra": "one more seed",
               "extra_redrawn": "one more seed, its readings drawn again"}


def _probe(child: FilterChild, sr: SimulatedRun, job: StudentJob, findings: dict[str, Any],
           graded: TaskResult) -> bool:
    """The probes of a filter that draws from the global generators (its runs fed one by
    one, each in a fresh child), one by one too: the first run's first :data:`PROBE_TICKS`
    ticks fed again with the global generators seeded differently (is it deterministic?),
    and the extra run fed its readings and its readings drawn again, the global generators
    seeded alike (does it use them?). Returns whether the child may be used again (False
    when a probe broke it)."""
    if not isinstance(graded.run, RunOutput):
        return True
    fr = next(iter(graded.run.filters.values()))
    if fr.failed or fr.means is None:
        return True
    n = min(PROBE_TICKS, len(sr.frames))
    first = fr.means[:n]
    name = child.class_name
    failures: dict[str, tuple[str, int]] = {}
    _, rep = isolated_run(child, sr, job.time_limit, global_seed=sr.global_seed(name) ^ 1, ticks=n)
    if rep.get("failed"):
        failures["again"] = (str(rep["failed"]), int(np.argmax(np.isnan(rep["means"][:, 0]))))
    if rep.get("failed_child"):
        _probe_findings(sr, ProbeFindings(False, None, None, failures), findings)
        return False
    deterministic = bool(np.array_equal(rep["means"], first, equal_nan=True))
    used = None
    ex = sr.extra
    if ex is not None and ex.frames_other is not None and ex.readings_within(len(ex.frames)):
        means = []
        for what, other in (("extra", False), ("extra_redrawn", True)):
            _, rep = isolated_run(child, ex, job.time_limit, other=other, ticks=len(ex.frames), name=name,
                                  global_seed=ex.global_seed(name))
            if rep.get("failed") and not failures.get("extra"):
                failures[what] = (str(rep["failed"]), int(np.argmax(np.isnan(rep["means"][:, 0]))))
            means.append(None if rep.get("failed") else rep["means"])
            if rep.get("failed_child"):
                _probe_findings(sr, ProbeFindings(deterministic, None, None, failures), findings)
                return False
        if means[0] is not None and means[1] is not None:
            used = not bool(np.array_equal(means[0], means[1], equal_nan=True))
    _probe_findings(sr, ProbeFindings(deterministic, None, used, failures), findings)
    return True


def run_students(jobs_list: Sequence[StudentJob], jobs: int | None = None, scheduler: Any = None,
                 progress: Callable[[int, int], None] | None = None) -> list[StudentResult]:
    """Every student's job, in order: ``jobs`` at once on local threads (each drives its
    student's child process, where the work is), or as Dask tasks (``scheduler``) whose
    results are released once gathered (nothing finished is computed again)."""
    out: list[StudentResult | None] = [None] * len(jobs_list)
    total = sum(len(j.sims) + len(j.team_sims) for j in jobs_list)
    done = 0

    def finish(i: int, res: StudentResult) -> None:
        nonlocal done
        out[i] = res
        done += len(res.results)
        if progress:
            progress(done, total)

    if scheduler is not None:
        def lost(i: int, exc: Exception) -> None:  # the worker itself was lost (not the child)
            job = jobs_list[i]
            runs: list[SimulatedRun | TeamSimulated] = [*job.sims, *job.team_sims]
            finish(i, StudentResult(job.student, [
                TaskResult(Task(job.student, job.filename, sr.label, sr.seed, None,
                                job.time_limit, sr.index), None,
                           f"worker lost: {type(exc).__name__}") for sr in runs],
                {}, "", job.sandbox))

        sims = jobs_list[0].sims if jobs_list else []
        team_sims = jobs_list[0].team_sims if jobs_list else []
        if all(j.sims is sims and j.team_sims is team_sims for j in jobs_list):  # sent to each worker once
            light = [dataclasses.replace(j, sims=[], team_sims=[]) for j in jobs_list]
            on_dask(scheduler, run_student_shared, light, finish, lost=lost, shared=(sims, team_sims))
        else:
            on_dask(scheduler, run_student, list(jobs_list), finish, lost=lost)
    else:
        from concurrent.futures import ThreadPoolExecutor

        # One more student than cores: a student's thread and its child take turns (lockstep),
        # so cores + 1 keeps every core busy (measured: 20 % less wall time on 2 cores).
        n = default_jobs() + 1 if jobs is None else max(1, int(jobs))
        with ThreadPoolExecutor(max_workers=max(1, min(n, len(jobs_list)))) as pool:
            futs = {pool.submit(run_student, j): i for i, j in enumerate(jobs_list)}
            for fut, i in futs.items():
                finish(i, fut.result())
    return [r for r in out if r is not None]


def _svg_plot(curves: list[tuple[str, np.ndarray, np.ndarray]], width: int = 320,
              height: int = 110) -> str:
    """A small inline SVG of position error [m] against time [s], one line per scenario."""
    colours = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd"]
    finite = [e[np.isfinite(e)] for _, _, e in curves]
    top = max([float(np.max(f)) for f in finite if len(f)] + [1e-3])
    tmax = max([float(t[-1]) for _, t, _ in curves if len(t)] + [1.0])
    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
             f'viewBox="0 0 {width} {height}"><rect width="100%" height="100%" fill="#fff"/>']
    for k, (label, t, e) in enumerate(curves):
        pts = " ".join(f"{4 + (width - 8) * ti / tmax:.1f},{height - 14 - (height - 24) * ei / top:.1f}"
                       for ti, ei in zip(t[::4], e[::4], strict=True) if math.isfinite(ei))
        parts.append(f'<polyline fill="none" stroke="{colours[k % 4]}" stroke-width="1.2" '
                     f'points="{pts}"><title>{html.escape(label)}</title></polyline>')
    parts.append(f'<text x="4" y="10" font-size="9">{top:.2g} m</text>'
                 f'<text x="{width - 40}" y="{height - 2}" font-size="9">{tmax:.0f} s</text></svg>')
    return "".join(parts)


def scenario_labels(scenarios: Sequence[str]) -> dict[str, str]:
    """Configured scenario -> how the leaderboard names it: a shipped scenario by its name, a
    file by its file name, never the folders it is in (grade.json and the pages are shared);
    a file name that two of them share gets `` (2)``, `` (3)``... after it."""
    from beacon_sim.io.export import without_folders

    out: dict[str, str] = {}
    for spec in scenarios:
        label = base = without_folders(spec)
        k = 1
        while label in out.values():
            k += 1
            label = f"{base} ({k})"
        out[spec] = label
    return out


def grade(folder: str | Path, config: GradeConfig = GradeConfig(), jobs: int | None = None,
          scheduler: Any = None, progress: Callable[[int, int], None] | None = None,
          cache: str | Path | None = None, secret: bytes | None = None) -> dict[str, Any]:
    """Grade every filter file in ``folder``; returns the leaderboard (``rows`` in rank
    order, ``config``, ``wall_s``, ``sandbox``, ``logs``, ``secret``) that
    :func:`write_outputs` writes.

    ``secret`` keys every student's random streams (``ctx.rng`` and the global generators'
    seeds: core/streams.py), so nothing a filter is given reveals a run's seed; None draws
    a new one (:data:`~beacon_sim.core.streams.SECRET_BYTES` random bytes). It never
    reaches a child. The same secret (``board["secret"]``, kept by :func:`write_outputs` in
    ``grade.secret``) grades every file again bit for bit, alone or in a class.

    Each single-robot (scenario, seed) is simulated once, here; each student's filter runs
    in a child process of its own (:func:`run_student`) that receives only what a filter
    may see; the scoring stays here. A team scenario's (scenario, seed) is simulated once too
    (:func:`simulate_team_run`) and each robot's ticks streamed to the student's child, one
    copy of the filter per robot.

    ``cache``: a folder of earlier results, by the file's hash and the configuration
    (:func:`cache_key`): a student whose file and settings are unchanged is not run again
    (re-grading one late or corrected file costs that file alone).

    The leaderboard names each scenario by :func:`scenario_labels` (a file by its file name,
    never its folder); the runs load them by the configured name or path."""
    t0 = time.perf_counter()
    secret = new_secret() if secret is None else check_secret(secret)
    students = find_students(folder, config.class_name)
    labels = scenario_labels(config.scenarios)
    specs = {label: spec for spec, label in labels.items()}
    config, given = dataclasses.replace(config, scenarios=tuple(labels[s] for s in config.scenarios)), config
    try:
        scenarios: dict[str, Scenario | TeamScenario] = {
            labels[s]: load_team_scenario(s) if is_team_scenario(s) else load_scenario(s)
            for s in given.scenarios}
        sandbox = resolve_sandbox(config.sandbox)
    except (ValueError, SandboxError) as exc:  # ScenarioError: one line
        raise GradeError(str(exc)) from None
    team_names = [n for n, sc in scenarios.items() if isinstance(sc, TeamScenario)]
    single = [n for n in config.scenarios if n not in team_names]
    sims: list[SimulatedRun] = []
    for n in single:
        sc = scenarios[n]
        assert isinstance(sc, Scenario)
        duration = sc.duration if config.duration is None else config.duration
        for i, seed in enumerate(config.seeds):
            sims.append(simulate_run(sc, seed, duration, i, probe=not sims, label=n, secret=secret))
    team_sims: list[TeamSimulated] = []
    for n in team_names:
        team = scenarios[n]
        assert isinstance(team, TeamScenario)
        duration = team.duration if config.duration is None else config.duration
        team_sims += [simulate_team_run(team, seed, duration, i, n, secret)
                      for i, seed in enumerate(config.seeds)]
    student_jobs = [StudentJob(st.name, st.path.name,
                               read_user_bytes(st.path, what="filter file", cap=MAX_SOURCE_BYTES,
                                               error=GradeError),
                               config.class_name or st.class_name, sims, config.time_limit,
                               config.memory_limit_gb, sandbox, team_sims)
                    for st in students if st.spec and (sims or team_sims)]
    if cache is not None and not _students_cannot_write_here(sandbox):
        cache = None  # a child running as this user could plant a pickle: no cache
    done_students, cached = _run_cached(student_jobs, jobs, scheduler, progress,
                                        Path(cache) if cache is not None else None)
    results = [r for sr in done_students for r in sr.results]
    # The team reference runs in process (a worker loads the scenario by its configured name
    # or path; the result takes its label).
    tasks = [Task(REFERENCE, REFERENCE_SPEC, specs[sc], seed, config.duration, config.time_limit, i)
             for sc in team_names for i, seed in enumerate(config.seeds)]
    if tasks:
        results += [dataclasses.replace(r, task=dataclasses.replace(r.task, scenario=labels[r.task.scenario]))
                    for r in run_tasks(tasks, jobs, scheduler, config.memory_limit_gb, None)]
    by: dict[tuple[str, str], list[TaskResult]] = {}
    for r in results:
        by.setdefault((r.task.student, r.task.scenario), []).append(r)
    rows = []
    n_runs = len(config.scenarios) * len(config.seeds)
    reference = {}
    for name in team_names:
        runs = [r.run for r in sorted(by.get((REFERENCE, name), []), key=lambda r: r.task.index)]
        if runs and all(isinstance(r, TeamRunOutput) for r in runs):
            ref = _team_figures(scenarios[name], runs)  # type: ignore[arg-type]
            reference[name] = {k: v for k, v in ref.items() if k != "curve"}
    found = {sr.student: sr for sr in done_students}
    scored = _score_together(scenarios, single, by, students, len(config.seeds))
    slam_names = [n for n in single if is_slam_scenario(scenarios[n])]
    slam_reference = _slam_reference(sims, slam_names)
    scan_reference = _scan_reference(scenarios, [n for n in single if is_scan_scenario(scenarios[n])],
                                     config)
    for st in students:
        done = found.get(st.name)
        row = _student_row(st, config, scenarios, by, n_runs, reference, scored, slam_reference,
                           done.findings.get("probe_failures") or () if done is not None else ())
        for name, ref in scan_reference.items():  # a scan assignment: the row beside mcl's
            got = scored.get((st.name, name))
            mine = got[0].get("pos_rmse_m") if got is not None and not row["failed_runs"] else None
            theirs = ref["pos_rmse_m"]
            row.setdefault("scan", {})[name] = {
                "pos_rmse_m": mine, "reference_pos_rmse_m": theirs,
                "over_reference": mine / theirs if mine is not None and theirs else None}
        _add_findings(row, found.get(st.name))
        rows.append(row)
    rows.sort(key=rank_key)
    for k, row in enumerate(rows, 1):
        row["rank"] = k
    return {"rows": rows, "config": asdict(config), "wall_s": time.perf_counter() - t0,
            "students": len(students), "runs_per_student": n_runs, "reference": reference,
            "slam_reference": slam_reference, "scan_reference": scan_reference,
            "sandbox": sandbox, "isolated": True, "team_in_process": [],
            "cached_students": cached,
            # the key of every student's random streams: kept in grade.secret, never in grade.json
            "secret": secret.hex(), "secret_sha256": secret_fingerprint(secret),
            # what the students' children said they used [s] (their own word: cost figures only)
            "child_cpu_s": sum(float(sr.findings.get("child_cpu_s", 0.0)) for sr in done_students),
            "logs": {sr.student: sr.log for sr in done_students}}


#: The file in a grade's output folder that keeps the grade's secret (hex), readable by its
#: owner only: ``grade --secret-file`` takes it back (docs/grading.md, "The grade's secret").
SECRET_FILE = "grade.secret"


def new_secret() -> bytes:
    """A fresh secret for a grade: :data:`~beacon_sim.core.streams.SECRET_BYTES` bytes from
    the operating system's generator."""
    import secrets

    from beacon_sim.core.streams import SECRET_BYTES

    return secrets.token_bytes(SECRET_BYTES)


def check_secret(secret: bytes) -> bytes:
    """``secret`` if it can key a grade (at least 16 bytes), else :class:`GradeError`."""
    if not isinstance(secret, bytes | bytearray) or len(secret) < 16:
        raise GradeError("a grade's secret must be at least 16 bytes (32 hex digits)")
    return bytes(secret)


def secret_fingerprint(secret: bytes) -> str:
    """16 hex digits that name a secret without giving it away (``grade.json`` keeps them, so
    a secret file can be matched to the grade it made)."""
    import hashlib

    return hashlib.sha256(b"beacon-sim grade secret " + secret).hexdigest()[:16]


def read_secret(path: str | Path) -> bytes:
    """The secret kept in ``path`` (hex digits, as :func:`write_outputs` writes it);
    :class:`GradeError` naming what is wrong."""
    try:
        text = Path(path).read_text(encoding="ascii").strip()
    except (OSError, UnicodeDecodeError) as exc:
        raise GradeError(f"{path}: cannot read the grade's secret: {exc}") from None
    try:
        secret = bytes.fromhex(text)
    except ValueError:
        raise GradeError(f"{path}: expected the grade's secret as hex digits (the {SECRET_FILE} "
                         "a grade wrote)") from None
    try:
        return check_secret(secret)
    except GradeError as exc:
        raise GradeError(f"{path}: {exc}") from None


def write_secret(secret_hex: str, path: Path) -> Path:
    """Keep a grade's secret in ``path``, readable and writable by its owner only."""
    import os

    path.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w", encoding="ascii") as fh:
        fh.write(secret_hex + "\n")
    os.chmod(path, 0o600)
    return path


def _students_cannot_write_here(sandbox: str) -> bool:
    """Whether the students' children cannot write the grader's files (the cache of pickles
    is read back): inside bubblewrap, or as ``nobody`` under a root grader."""
    import os

    return sandbox == "bwrap" or (hasattr(os, "geteuid") and os.geteuid() == 0)


def cache_key(job: StudentJob) -> str:
    """A student's results are reused when this is unchanged: the file's bytes and name, the
    class, the limits, the sandbox level, beacon-sim's version and every simulated run
    (scenario, seed, length, the truth's checksum)."""
    import hashlib

    from beacon_sim.version import __version__

    h = hashlib.sha256(job.source)
    meta = [job.filename, job.class_name, job.time_limit, job.memory_limit_gb, job.sandbox, __version__,
            PROBE_TICKS, [(sr.label, sr.seed, len(sr.frames), sr.truth_checksum, repr(sr.scenario),
                           hashlib.sha256(sr.stream_key).hexdigest())  # the secret's mark, not it
                          for sr in job.sims],
            [(ts.label, ts.seed, len(ts.robots[0].frames), ts.truth_checksum,
              [repr(r.scenario) for r in ts.robots], hashlib.sha256(ts.robots[0].stream_key).hexdigest())
             for ts in job.team_sims]]
    h.update(json.dumps(meta, default=str).encode())
    return h.hexdigest()


def _run_cached(student_jobs: list[StudentJob], jobs: int | None, scheduler: Any,
                progress: Callable[[int, int], None] | None, cache: Path | None
                ) -> tuple[list[StudentResult], list[str]]:
    """:func:`run_students` for the students whose results are not in ``cache`` (a folder of
    pickles the grader wrote itself: numbers and texts, nothing of a student's code); the
    others' results from it. Returns the results in order and the students taken from it."""
    import pickle

    if cache is None:
        return (run_students(student_jobs, jobs, scheduler, progress) if student_jobs else []), []
    cache.mkdir(parents=True, exist_ok=True)
    found: dict[int, StudentResult] = {}
    for i, job in enumerate(student_jobs):
        f = cache / f"{cache_key(job)}.pickle"
        if f.is_file():
            try:
                found[i] = pickle.loads(f.read_bytes())
            except Exception:  # a damaged entry: run the student again
                pass
    todo = [j for i, j in enumerate(student_jobs) if i not in found]
    fresh = iter(run_students(todo, jobs, scheduler, progress) if todo else [])
    out = []
    for i, job in enumerate(student_jobs):
        if i in found:
            out.append(found[i])
            continue
        res = next(fresh)
        out.append(res)
        if any(r.problem and r.problem.startswith("worker lost") for r in res.results):
            continue  # the machine's failure, not the student's: run it again next time
        tmp = cache / f".{cache_key(job)}.tmp"
        tmp.write_bytes(pickle.dumps(res, protocol=pickle.HIGHEST_PROTOCOL))
        tmp.replace(cache / f"{cache_key(job)}.pickle")
    return out, [student_jobs[i].student for i in sorted(found)]


#: A result this far below the bound is "suspicious" (RMSE/PCRB), and an ANEES below this
#: (errors far smaller than the filter's own covariance says: 3 is consistent).
SUSPICIOUS_RMSE_OVER_PCRB = 0.5
SUSPICIOUS_ANEES = 0.1


def _add_findings(row: dict[str, Any], res: StudentResult | None) -> None:
    """The row's flags: suspicious (kept out of the ranking), and ``check``'s findings
    (global RNG, deterministic, heading wrapped, readings used, time per step) as columns
    and warnings."""
    flags: list[str] = []
    f = res.findings if res is not None else {}
    row["global_rng"] = f.get("global_rng")
    row["deterministic"] = f.get("deterministic")
    row["heading_wrapped"] = f.get("heading_wrapped") if res is not None else None
    row["readings_used"] = f.get("readings_used")
    row["form"] = f.get("form")
    row["log"] = bool(res and res.log)
    row["suspicious"] = None
    if not row["failed_runs"]:
        ratio, anees = row.get("rmse_over_pcrb"), row.get("anees")
        if ratio is not None and ratio < SUSPICIOUS_RMSE_OVER_PCRB:
            row["suspicious"] = (f"RMSE/PCRB {ratio:.2f} is under {SUSPICIOUS_RMSE_OVER_PCRB:g}: "
                                 "better than the bound allows")
        elif anees is not None and anees < SUSPICIOUS_ANEES:
            row["suspicious"] = (f"ANEES {anees:.3f} is far below its band (3 is consistent): errors "
                                 "far smaller than the filter's own covariance")
    if row["suspicious"]:
        flags.append("suspicious: " + row["suspicious"])
    if row["global_rng"]:
        flags.append("draws from the global np.random / random generator (reproducible here "
                     "only because the grader seeds them from the grade's secret; use ctx.rng)")
    if row["deterministic"] is False:
        flags.append("not deterministic: the same run fed again gives other estimates (or, for a "
                     "filter that draws from the global generators, their seed alone changes them)")
    if row["heading_wrapped"] is False:
        flags.append("heading not wrapped to [-pi, pi)")
    if row["readings_used"] is False:
        flags.append("uses none of the readings: the estimates do not change when the readings are "
                     "drawn again")
    unmapped = [] if row["failed_runs"] else [n for n, v in (row.get("slam") or {}).items()
                                              if not v.get("mapped")]
    if unmapped:
        flags.append(f"no landmarks(): the filter reports no map, so its map is not scored on "
                     f"{', '.join(unmapped)} (docs/slam.md)")
    if row.get("us_per_step") is not None and row["us_per_step"] > SLOW_STEP_MS * 1e3:
        flags.append(f"slow: {row['us_per_step'] / 1e3:.0f} ms per step (over {SLOW_STEP_MS:g} ms)")
    row["flags"] = flags


def is_slam_scenario(sc: Scenario | TeamScenario) -> bool:
    """A single-robot scenario whose beacon map is withheld from the filters (docs/slam.md)."""
    return isinstance(sc, Scenario) and not sc.map_known


def run_slam_figures(sc: Scenario, err: np.ndarray, landmarks: tuple[Any, Any, Any] | None,
                     joint: tuple[Any, Any, Any] | None, final_pose: np.ndarray) -> dict[str, Any]:
    """One run's SLAM figures (:data:`SLAM_FIGURES`) from the filter's pose errors ``err``
    (T, 3), its final map ``(ids, means, covs)`` (None: no ``landmarks()``, no map figures)
    and its final ``joint()`` (None: no joint NEES), against the truth of ``sc``."""
    out: dict[str, Any] = dict.fromkeys(SLAM_FIGURES)
    out["ate_m"] = ate(err[:, :2], np.zeros((len(err), 2)))
    if landmarks is not None:
        means = np.asarray(landmarks[1], dtype=float).reshape(-1, 2)
        g = gospa(means, mapped_beacons(sc)[1], c=GOSPA_CUTOFF_M)
        out.update(map_gospa_m=g.value, map_landmarks=len(means), map_missed=g.missed, map_false=g.false)
    if joint is not None:
        try:
            out["joint_nees"] = joint_nees_at(joint, sc, final_pose)[0]
        except (np.linalg.LinAlgError, ValueError, IndexError, KeyError):
            out["joint_nees"] = None  # a singular or malformed joint: not reported
    return out


def _mean_figures(per_run: list[dict[str, Any]]) -> dict[str, Any]:
    """The seed mean of each SLAM figure, None unless every run has it."""
    out: dict[str, Any] = {}
    for k in SLAM_FIGURES:
        vals = [r[k] for r in per_run]
        out[k] = (float(np.mean(vals)) if vals and all(v is not None and math.isfinite(v) for v in vals)
                  else None)
    return out


def reference_slam_run(sr: SimulatedRun, spec: str = SLAM_REFERENCE_SPEC) -> dict[str, Any] | None:
    """The built-in ``spec`` (EKF-SLAM) fed the simulated run ``sr`` in this process (a
    built-in filter: trusted code; the grader's own pickled ticks), its SLAM figures; None
    when it failed (a built-in that raises or diverges there says nothing of the students)."""
    import pickle

    from beacon_sim.hosting.loading import build_filter

    try:
        flt: Any = build_filter(spec, sr.scenario, sr.seed, name=spec)
        means = np.empty((len(sr.frames), 3))
        for i, frame in enumerate(sr.frames):
            _op, control, dt, meas, _want_prior = pickle.loads(frame[4:])
            flt.predict(control, dt)
            flt.update(meas)
            means[i] = flt.estimate()[0]
        lm = flt.landmarks()
        joint = flt.joint() if callable(getattr(flt, "joint", None)) else None
    except Exception:
        return None
    err = means - sr.truth[1:]
    return run_slam_figures(sr.scenario, err, (lm.ids, lm.means, lm.covs), joint, sr.truth[-1])


def _slam_reference(sims: list[SimulatedRun], names: list[str]) -> dict[str, dict[str, Any]]:
    """The built-in EKF-SLAM's seed-mean SLAM figures on each SLAM scenario ``names``."""
    out = {}
    for name in names:
        per = [reference_slam_run(sr) for sr in sims if sr.label == name]
        out[name] = ({"filter": SLAM_REFERENCE_SPEC, **_mean_figures(per)} if per and all(per)  # type: ignore[arg-type]
                     else {"filter": SLAM_REFERENCE_SPEC, **dict.fromkeys(SLAM_FIGURES)})
    return out


def is_scan_scenario(sc: Scenario | TeamScenario) -> bool:
    """A single-robot map world (walls) with a range finder: a scan-based assignment."""
    return (isinstance(sc, Scenario) and sc.world.grid is not None
            and any(s.kind == "range_finder" for s in sc.model_sensors))


def _scan_reference(scenarios: dict[str, Scenario | TeamScenario], names: list[str],
                    config: GradeConfig) -> dict[str, dict[str, Any]]:
    """The built-in ``mcl``'s figures (position and heading RMSE, ANEES) on each scan
    scenario ``names``, run in process (a built-in filter: trusted) on the config's seeds:
    :func:`~beacon_sim.evaluation.montecarlo.one_run`, the path ``eval`` takes."""
    out: dict[str, dict[str, Any]] = {}
    for name in names:
        sc = scenarios[name]
        assert isinstance(sc, Scenario)
        duration = sc.duration if config.duration is None else config.duration
        try:
            runs = [one_run(sc, [SCAN_REFERENCE_SPEC], {}, seed, duration, index=i)
                    for i, seed in enumerate(config.seeds)]
            fr = evaluate(sc, runs, Thresholds())[0]["filters"][SCAN_REFERENCE_SPEC]
        except Exception:  # a built-in that fails there says nothing of the students
            fr = {}
        out[name] = {"filter": SCAN_REFERENCE_SPEC,
                     **{k: fr.get(k) for k in ("pos_rmse_m", "heading_rmse_rad", "anees")}}
    return out


def _team_figures(team: TeamScenario, runs: list[TeamRunOutput]) -> dict[str, Any]:
    """A graded filter's figures on a team scenario (its one team filter): the team's, each
    robot's, its failures, and its first seed's position error averaged over the robots."""
    meta = evaluate_team(team, runs)
    name, fr = next(iter(meta["filters"].items()))
    t = fr["team"]
    err = np.mean([np.hypot(f.err[:, 0], f.err[:, 1]) for f in runs[0].filters[name]], axis=0)
    return {"pos_rmse_m": t["pos_rmse_m"], "heading_rmse_rad": t["heading_rmse_rad"],
            "anees": t["anees"], "anees_verdict": t["anees_verdict"],
            "rmse_over_pcrb": t["rmse_over_pcrb_alone"], "us_per_step": fr["us_per_step"],
            "robots": {rn: {k: v[k] for k in ("pos_rmse_m", "heading_rmse_rad", "anees", "anees_verdict",
                                              "rmse_over_pcrb_alone")}
                       for rn, v in fr["robots"].items()},
            "failures": fr["failures"],
            "curve": (meta["dt"] * np.arange(1, meta["steps"] + 1), err)}


def _score_together(scenarios: dict[str, Scenario | TeamScenario], names: list[str],
                    by: dict[tuple[str, str], list[TaskResult]], students: list[Student],
                    n_seeds: int) -> dict[tuple[str, str], tuple[dict[str, Any], dict[str, Any], Any]]:
    """Every student's runs of each single-robot scenario scored in one
    :func:`~beacon_sim.evaluation.summary.evaluate` (the bound, the same for all, computed
    once): (student, scenario) -> (its row of figures, its curves, the times). A filter's
    figures depend on its own runs and the truth only, so they are those of scoring it alone."""
    out: dict[tuple[str, str], tuple[dict[str, Any], dict[str, Any], Any]] = {}
    for name in names:
        sc = scenarios[name]
        whole = []
        for st in students:
            res = sorted(by.get((st.name, name), []), key=lambda r: r.task.index)
            if len(res) == n_seeds and all(isinstance(r.run, RunOutput) for r in res):
                whole.append((st.name, [r.run for r in res]))
        if not whole:
            continue
        merged = []
        for i in range(n_seeds):
            first: Any = whole[0][1][i]
            run = RunOutput(first.index, first.seed, first.truth, first.controls, first.kidnapped,
                            first.truth_checksum)
            for student, runs in whole:
                run.filters[student] = next(iter(runs[i].filters.values()))  # type: ignore[union-attr,assignment]
            merged.append(run)
        meta, curve = evaluate(sc, merged, Thresholds())  # type: ignore[arg-type]
        for student, _ in whole:
            out[(student, name)] = (meta["filters"][student], curve["filters"][student], curve["time"])
    return out


def _student_row(st: Student, config: GradeConfig, scenarios: dict[str, Scenario | TeamScenario],
                 by: dict[tuple[str, str], list[TaskResult]], n_runs: int,
                 reference: dict[str, dict[str, Any]] | None = None,
                 scored: dict[tuple[str, str], tuple[dict[str, Any], dict[str, Any], Any]] | None = None,
                 slam_reference: dict[str, dict[str, Any]] | None = None,
                 probe_failures: Sequence[dict[str, Any]] = ()) -> dict[str, Any]:
    """A student's row; ``probe_failures``: the probes its filter failed on its own (a probe
    is one more run: failing it fails the student, shown as a failed run)."""
    row: dict[str, Any] = {"student": st.name, "file": st.path.name, "runs": n_runs,
                           "pos_rmse_m": None, "heading_rmse_rad": None, "anees": None,
                           "anees_verdict": "FAILED", "verdict": "FAILED", "rmse_over_pcrb": None,
                           "us_per_step": None,
                           "failed_runs": n_runs, "failures": [], "plot": ""}
    if slam_reference:  # a SLAM assignment: the map columns (docs/grading.md)
        row.update(dict.fromkeys(("ate_m", "map_gospa_m", "joint_nees")))
    if st.spec is None:
        row["failures"] = [{"scenario": "-", "seed": None, "time_s": None, "reason": st.problem}]
        return row
    figures: dict[str, list[float]] = {k: [] for k in ("pos_rmse_m", "heading_rmse_rad", "anees",
                                                        "rmse_over_pcrb", "us_per_step")}
    verdicts, failures, curves = [], [], []
    team_rows: dict[str, Any] = {}
    slam_rows: dict[str, Any] = {}
    for name in config.scenarios:
        res = sorted(by.get((st.name, name), []), key=lambda r: r.task.index)
        for r in res:
            if r.run is None:
                failures.append({"scenario": name, "seed": r.task.seed, "time_s": None,
                                 "reason": r.problem})
        runs = [r.run for r in res if r.run is not None]
        if not runs:
            continue
        sc = scenarios[name]
        if isinstance(sc, TeamScenario):
            tf = _team_figures(sc, runs)  # type: ignore[arg-type]
            failures += [{"scenario": name, **f} for f in tf["failures"]]
            for key in figures:
                if tf.get(key) is not None:
                    figures[key].append(float(tf[key]))
            verdicts.append(tf["anees_verdict"])
            curves.append((f"{name} (mean over robots)", *tf["curve"]))
            ref = (reference or {}).get(name, {})
            team_rows[name] = {k: tf[k] for k in ("pos_rmse_m", "heading_rmse_rad", "anees",
                                                  "anees_verdict", "robots")}
            team_rows[name]["reference_pos_rmse_m"] = ref.get("pos_rmse_m")
            team_rows[name]["over_reference"] = (tf["pos_rmse_m"] / ref["pos_rmse_m"]
                                                 if tf["pos_rmse_m"] is not None and ref.get("pos_rmse_m")
                                                 else None)
            continue
        if (st.name, name) in (scored or {}):  # the class's runs scored together (one PCRB)
            fr, c, times = (scored or {})[(st.name, name)]
        else:
            meta, curve = evaluate(sc, runs, Thresholds())  # type: ignore[arg-type]
            fr = next(iter(meta["filters"].values()))
            c, times = next(iter(curve["filters"].values())), curve["time"]
        for f in fr["failures"]:
            failures.append({"scenario": name, **f})
        for key in figures:
            if fr.get(key) is not None:
                figures[key].append(float(fr[key]))
        verdicts.append(fr["anees_verdict"])
        curves.append((name, times, np.hypot(c["err0"][:, 0], c["err0"][:, 1])))
        if slam_reference and name in slam_reference and len(runs) == len(res):
            slam_rows[name] = _slam_row(sc, runs, slam_reference[name])  # type: ignore[arg-type]
    failures += list(probe_failures)
    row["failures"] = failures
    row["failed_runs"] = len(failures)
    row["run_detail"] = _run_detail(st, config, by)
    if team_rows:
        row["team"] = team_rows
    if slam_rows:
        row["slam"] = slam_rows
    row["us_per_step"] = float(np.mean(figures["us_per_step"])) if figures["us_per_step"] else None
    row["plot"] = _svg_plot(curves) if curves else ""
    if not failures:
        for key in ("pos_rmse_m", "heading_rmse_rad", "anees", "rmse_over_pcrb"):
            row[key] = float(np.mean(figures[key])) if figures[key] else None
        row["anees_verdict"] = verdicts[0] if len(set(verdicts)) == 1 else "/".join(verdicts)
        # what the page shows: the ANEES word with the distance from the bound (issue 26), so
        # no row says a bare "consistent" beside an error over twice the bound
        row["verdict"] = overall_verdict(row["anees_verdict"], row["rmse_over_pcrb"])
        for key in ("ate_m", "map_gospa_m", "joint_nees"):  # over the SLAM scenarios
            vals = [v[key] for v in slam_rows.values()]
            if slam_rows:
                row[key] = float(np.mean(vals)) if all(v is not None for v in vals) else None
    return row


def _slam_row(sc: Scenario, runs: list[RunOutput], ref: dict[str, Any]) -> dict[str, Any]:
    """A student's SLAM figures on one SLAM scenario (seed means, :data:`SLAM_FIGURES`),
    the reference's beside them, and whether the filter reported a map at all."""
    per = []
    mapped = True
    for run in runs:
        fr = next(iter(run.filters.values()))
        mapped &= fr.landmarks is not None
        per.append(run_slam_figures(sc, fr.err, fr.landmarks, fr.joint, run.truth[-1]))
    out = _mean_figures(per)
    out["mapped"] = mapped
    for key in ("ate_m", "map_gospa_m", "joint_nees"):
        out["reference_" + key] = ref.get(key)
    g, rg = out["map_gospa_m"], ref.get("map_gospa_m")
    out["gospa_over_reference"] = g / rg if g is not None and rg else None
    return out


def _run_detail(st: Student, config: GradeConfig, by: dict[tuple[str, str], list[TaskResult]]
                ) -> list[dict[str, Any]]:
    """One line per run of a student (the student's page): scenario, seed, position RMSE
    [m] over the steps it ran, steps, cost [us/step], and why it failed."""
    out = []
    for name in config.scenarios:
        for r in sorted(by.get((st.name, name), []), key=lambda r: r.task.index):
            line: dict[str, Any] = {"scenario": name, "seed": r.task.seed, "pos_rmse_m": None,
                                    "steps": 0, "us_per_step": None, "failed": r.problem}
            if isinstance(r.run, RunOutput):
                fr = next(iter(r.run.filters.values()))
                e = fr.err[np.isfinite(fr.err[:, 0]) & np.isfinite(fr.err[:, 1])]
                rmse = float(np.sqrt(np.mean(e[:, 0] ** 2 + e[:, 1] ** 2))) if len(e) else None
                line.update(pos_rmse_m=rmse, steps=int(fr.steps),
                            us_per_step=fr.step_ns / 1e3 / max(fr.steps, 1), failed=fr.failed)
            out.append(line)
    return out


def rank_key(row: dict[str, Any]) -> tuple:
    """Working filters first by position RMSE, then suspicious ones (kept out of the
    ranking), then failed ones (fewest failed runs first): a failed filter never ranks
    above a working one."""
    failed = row["failed_runs"] > 0
    rmse = row["pos_rmse_m"] if row["pos_rmse_m"] is not None else math.inf
    return (failed, bool(row.get("suspicious")), row["failed_runs"] if failed else 0, rmse,
            row["student"])


CSV_COLUMNS = ("rank", "student", "file", "status", "pos_rmse_m", "heading_rmse_rad", "anees",
               "anees_verdict", "verdict", "rmse_over_pcrb", "us_per_step", "failed_runs", "runs",
               "failures", "suspicious", "global_rng", "deterministic", "heading_wrapped", "readings_used",
               "flags")
#: The map columns a SLAM assignment adds (after :data:`CSV_COLUMNS`; seed means over the
#: SLAM scenarios; empty for a failed filter, and the map's for a filter without one).
SLAM_CSV_COLUMNS = ("ate_m", "map_gospa_m", "joint_nees")


def status(row: dict[str, Any]) -> str:
    """FAILED (no score), SUSPICIOUS (kept out of the ranking) or ok."""
    if row["failed_runs"]:
        return "FAILED"
    return "SUSPICIOUS" if row.get("suspicious") else "ok"


def _yes_no(v: object) -> str:
    return "" if v is None else ("yes" if v else "no")


def _failure_text(f: dict[str, Any]) -> str:
    where = "" if f.get("seed") is None else f"{f['scenario']} seed {f['seed']}"
    at = "" if f.get("time_s") is None else f" at {f['time_s']:.2f} s"
    return f"{where}{at}: {f['reason']}" if where else str(f["reason"])


def write_csv(board: dict[str, Any], path: Path) -> Path:
    """One row per student, in rank order; a failed student's figures are empty cells."""
    slam = bool(board.get("slam_reference"))
    with atomic_write(path, "w", newline="", what="grade table", error=GradeError) as fh:
        w = csv.writer(fh)
        w.writerow(CSV_COLUMNS + (SLAM_CSV_COLUMNS if slam else ()))
        for r in board["rows"]:
            extra = ["" if r.get(k) is None else r[k] for k in SLAM_CSV_COLUMNS] if slam else []
            w.writerow([r["rank"], r["student"], r["file"], status(r),
                        *("" if r[k] is None else r[k] for k in ("pos_rmse_m", "heading_rmse_rad",
                                                                 "anees")),
                        r["anees_verdict"], r.get("verdict", r["anees_verdict"]),
                        "" if r["rmse_over_pcrb"] is None else r["rmse_over_pcrb"],
                        "" if r["us_per_step"] is None else f"{r['us_per_step']:.1f}",
                        r["failed_runs"], r["runs"],
                        " | ".join(_failure_text(f) for f in r["failures"][:5]),
                        r.get("suspicious") or "", *(_yes_no(r.get(k)) for k in (
                            "global_rng", "deterministic", "heading_wrapped", "readings_used")),
                        " | ".join(r.get("flags", [])), *extra])
    return path


_CSS = """body{font-family:sans-serif;margin:1.5em;color:#222}table{border-collapse:collapse}
th,td{border:1px solid #ccc;padding:4px 8px;vertical-align:top}th{background:#eef;cursor:pointer}
tr.failed td{background:#fdecea}tr.suspicious td{background:#fff3cd}
.flag{font-size:85%;color:#8a5a00;max-width:28em}td.num{text-align:right;font-variant-numeric:tabular-nums}
.why{font-size:85%;color:#a00;max-width:28em}.note{color:#555;font-size:90%}"""

_JS = """
function sortBy(col, dir) {
  var body = document.getElementById('board').tBodies[0];
  var rows = Array.prototype.slice.call(body.rows);
  rows.sort(function (a, b) {
    var fa = +a.dataset.failed, fb = +b.dataset.failed;
    if (fa !== fb) return fa - fb;            /* a failed filter never above a working one */
    var x = a.dataset[col], y = b.dataset[col];
    var nx = parseFloat(x), ny = parseFloat(y);
    var c = (isNaN(nx) || isNaN(ny)) ? String(x).localeCompare(String(y)) : nx - ny;
    if (isNaN(nx) !== isNaN(ny)) c = isNaN(nx) ? 1 : -1;
    return dir * c;
  });
  rows.forEach(function (r) { body.appendChild(r); });
  document.getElementById('board').dataset.sorted = col + (dir > 0 ? '' : '-desc');
}
document.querySelectorAll('#board th[data-col]').forEach(function (th) {
  th.addEventListener('click', function () {
    var d = th.dataset.dir === '1' ? -1 : 1; th.dataset.dir = String(d); sortBy(th.dataset.col, d);
  });
});
var m = /sort=([a-z_]+)(-desc)?/.exec(location.hash);
if (m) sortBy(m[1], m[2] ? -1 : 1);
"""


def _reference_note(board: dict[str, Any]) -> str:
    """The HTML note's sentence on team scenarios: how a filter is graded there, and the
    built-in independent EKF's figures on the same seeds."""
    ref = board.get("reference") or {}
    if not ref:
        return ""
    parts = [f"{html.escape(n)}: {r['pos_rmse_m']:.4f} m, ANEES {r['anees']:.2f}"
             if r["pos_rmse_m"] is not None else f"{html.escape(n)}: failed" for n, r in ref.items()]
    return (" On a team scenario each student's filter is every robot's own filter (beacon readings "
            "only); its figures are the team's (RMSE over all robots, mean ANEES; RMSE/PCRB against "
            "each robot's bound alone). The built-in independent EKF on the same seeds: "
            + "; ".join(parts) + ".")


def _slam_note(board: dict[str, Any]) -> str:
    """The HTML note's sentence on SLAM scenarios: what the map columns mean, and the
    built-in EKF-SLAM's figures on the same seeds."""
    ref = board.get("slam_reference") or {}
    if not ref:
        return ""

    def num(v: object, fmt: str) -> str:
        return "&ndash;" if v is None else format(v, fmt)

    parts = [f"{html.escape(n)}: ATE {num(r['ate_m'], '.4f')} m, map GOSPA {num(r['map_gospa_m'], '.4f')} m, "
             f"joint NEES {num(r['joint_nees'], '.2f')}" for n, r in ref.items()]
    return (f" On a SLAM scenario (the filters are not given the beacon map) ATE is the path's RMS "
            f"position error, map GOSPA the error of the final map against the beacons it had to map "
            f"(cut-off {GOSPA_CUTOFF_M:g} m: a missed or a false landmark costs as much as one "
            f"{GOSPA_CUTOFF_M / math.sqrt(2):.2f} m off), joint NEES the final pose-and-map NEES "
            f"(for a filter with joint(); chi-square with 3 + 2M degrees of freedom), seed means. "
            f"The built-in {SLAM_REFERENCE_SPEC} on the same seeds: " + "; ".join(parts) + ".")


def _scan_note(board: dict[str, Any]) -> str:
    """The HTML note's sentence on scan scenarios: the built-in mcl's figures there."""
    ref = board.get("scan_reference") or {}
    if not ref:
        return ""
    parts = [f"{html.escape(n)}: {r['pos_rmse_m']:.4f} m" if r.get("pos_rmse_m") is not None
             else f"{html.escape(n)}: failed" for n, r in ref.items()]
    return (f" On a map world with a range finder each filter gets the occupancy grid (ctx.world.grid) "
            f"and the scans, never the pose; the built-in {SCAN_REFERENCE_SPEC} on the same seeds, "
            "position RMSE: " + "; ".join(parts) + ".")


def _notes(board: dict[str, Any]) -> str:
    """The page note's sentences on the team, SLAM and scan scenarios and their references."""
    return _reference_note(board) + _slam_note(board) + _scan_note(board)


def _sandbox_text(board: dict[str, Any]) -> str:
    level = board.get("sandbox", "process")
    text = ("bubblewrap sandbox: no network, read-only system, its own file alone" if level == "bwrap"
            else "process level: its own user, folder and limits, no OS sandbox")
    if board.get("team_in_process"):
        text += "; team scenarios in process, not isolated"
    return text


def pseudonym(student: str, board: dict[str, Any]) -> str:
    """A student's stable pseudonym on the class page: the same for the same class and
    configuration, not guessable from the name without the configuration's seeds."""
    import hashlib

    cfg = board["config"]
    key = f"{student}|{cfg['seeds']}|{cfg['scenarios']}".encode()
    return "student-" + hashlib.sha256(key).hexdigest()[:6]


def _shown(board: dict[str, Any]) -> dict[str, str]:
    """Student -> the name the class page shows (the pseudonym with ``pseudonyms``)."""
    anon = bool(board["config"].get("pseudonyms"))
    return {r["student"]: pseudonym(r["student"], board) if anon else r["student"] for r in board["rows"]}


def write_html(board: dict[str, Any], path: Path) -> Path:
    """A self-contained leaderboard page (inline CSS, JS and SVG plots): click a column
    to sort (``#sort=COLUMN`` or ``#sort=COLUMN-desc`` in the address sorts on load)."""
    cfg = board["config"]
    cols = [("rank", "rank"), ("student", "student"), ("pos_rmse_m", "pos RMSE [m]"),
            ("heading_rmse_rad", "heading RMSE [rad]"), ("anees", "ANEES"),
            ("verdict", "consistency"), ("rmse_over_pcrb", "RMSE/PCRB"),
            ("us_per_step", "cost [us/step]"), ("failed_runs", "failed runs")]
    if board.get("slam_reference"):  # a SLAM assignment: the map columns
        cols[3:3] = [("ate_m", "ATE [m]"), ("map_gospa_m", "map GOSPA [m]"), ("joint_nees", "joint NEES")]

    def cell(r: dict[str, Any], key: str) -> str:
        v = r.get(key, r["anees_verdict"]) if key == "verdict" else r.get(key)
        if v is None:
            return '<td class="num">&ndash;</td>'
        if isinstance(v, float):
            two = ("anees", "rmse_over_pcrb", "joint_nees")
            fmt = ".1f" if key == "us_per_step" else (".2f" if key in two else ".4f")
            return f'<td class="num">{v:{fmt}}</td>'
        if isinstance(v, int):
            return f'<td class="num">{v}</td>'
        return f"<td>{html.escape(str(v))}</td>"

    body = []
    shown = _shown(board)
    for r0 in board["rows"]:
        r = {**r0, "student": shown[r0["student"]]}
        data = " ".join(f'data-{k}="{html.escape("" if r.get(k) is None else str(r[k]))}"' for k, _ in cols)
        why = "<br>".join(html.escape(_failure_text(f)) for f in r["failures"][:4])
        more = len(r["failures"]) - 4
        if more > 0:
            why += f"<br>... and {more} more"
        flags = "<br>".join(html.escape(f) for f in r.get("flags", []))
        st = status(r)
        kind = {"FAILED": "failed", "SUSPICIOUS": "suspicious"}.get(st, "ok")
        log = f' <a href="students/{html.escape(r["student"])}.html">page</a>'
        if r.get("log"):
            log += f' <a href="logs/{html.escape(r["student"])}.log">log</a>'

        order = {"ok": 0, "suspicious": 1, "failed": 2}[kind]  # the page's sort keeps this order
        body.append(f'<tr class="{kind}" data-failed="{order}" {data}>' + "".join(cell(r, k) for k, _ in cols)
                    + f'<td>{st}{log}<div class="why">{why}</div><div class="flag">{flags}</div></td>'
                    + f"<td>{r['plot']}</td></tr>")
    head = "".join(f'<th data-col="{k}">{html.escape(t)}</th>' for k, t in cols)
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>beacon-sim grade</title>
<style>{_CSS}</style></head><body>
<h1>Leaderboard</h1>
<p class="note">{board['students']} students, {board['runs_per_student']} runs each: scenarios
{html.escape(', '.join(cfg['scenarios']))}; seeds {html.escape(', '.join(map(str, cfg['seeds'])))};
{'each scenario' + chr(39) + 's duration' if cfg['duration'] is None else f"{cfg['duration']:g} s"} per run;
time limit {cfg['time_limit']:g} s per run. A filter that failed in any run has no score and
ranks below every working filter, whatever the column sorted; a suspicious result (far below
the Cramer-Rao bound) is kept out of the ranking, below the working filters, with its reason.
Each student's filter ran in a process of its own ({html.escape(_sandbox_text(board))}).
Click a column to sort.
Plot: position error [m] against time [s] of the first seed.{_notes(board)}</p>
<table id="board"><thead><tr>{head}<th>status and failures</th><th>error, first seed</th></tr></thead>
<tbody>
{chr(10).join(body)}
</tbody></table>
<script>{_JS}</script>
</body></html>
"""
    write_text_atomic(path, page, what="grade page", error=GradeError)
    return path


def write_student_page(board: dict[str, Any], row: dict[str, Any], path: Path, shown: str,
                       log: str) -> Path:
    """One student's page: the figures, each run, failures, warnings, the plot and the log."""
    def num(v: object, fmt: str) -> str:
        return "&ndash;" if v is None else format(v, fmt)

    runs = "".join(
        f"<tr><td>{html.escape(str(d['scenario']))}</td><td class=num>{d['seed']}</td>"
        f"<td class=num>{num(d['pos_rmse_m'], '.4f')}</td><td class=num>{d['steps']}</td>"
        f"<td class=num>{num(d['us_per_step'], '.1f')}</td>"
        f"<td class=why>{html.escape(d['failed'] or '')}</td></tr>" for d in row.get("run_detail", []))
    flags = "".join(f"<li>{html.escape(f)}</li>" for f in row.get("flags", []))
    fails = "".join(f"<li>{html.escape(_failure_text(f))}</li>" for f in row["failures"])
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{html.escape(shown)}: beacon-sim grade</title>
<style>{_CSS}</style></head><body>
<h1>{html.escape(shown)}</h1>
<p class="note"><a href="../grade.html">the class page</a>. Rank {row['rank']} of {board['students']};
status {status(row)}; position RMSE {num(row['pos_rmse_m'], '.4f')} m; heading RMSE
{num(row['heading_rmse_rad'], '.4f')} rad; ANEES {num(row['anees'], '.2f')}
({html.escape(str(row['anees_verdict']))});
RMSE/PCRB {num(row['rmse_over_pcrb'], '.2f')}; {num(row['us_per_step'], '.1f')} us per step.</p>
{_slam_table(row)}
<h2>Runs</h2>
<table><thead><tr><th>scenario</th><th>seed</th><th>pos RMSE [m]</th><th>steps</th><th>cost [us/step]</th>
<th>failure</th></tr></thead><tbody>{runs}</tbody></table>
{'<h2>Failures</h2><ul class="why">' + fails + '</ul>' if fails else ''}
{'<h2>Warnings</h2><ul class="flag">' + flags + '</ul>' if flags else ''}
<h2>Position error [m] against time [s], first seed</h2>{row['plot']}
<h2>Log (stdout and stderr, cut at {LOG_BYTES // 1024} KB)</h2>
<pre>{html.escape(log) or '(nothing printed)'}</pre>
</body></html>
"""
    write_text_atomic(path, page, what="grade page", error=GradeError)
    return path


def _slam_table(row: dict[str, Any]) -> str:
    """A student page's map figures, per SLAM scenario, beside the reference's."""
    slam = row.get("slam") or {}
    if not slam:
        return ""

    def num(v: object, fmt: str) -> str:
        return "&ndash;" if v is None else format(v, fmt)

    keys = (("ate_m", ".4f"), ("reference_ate_m", ".4f"), ("map_gospa_m", ".4f"),
            ("reference_map_gospa_m", ".4f"), ("map_landmarks", ".1f"), ("map_missed", ".1f"),
            ("map_false", ".1f"), ("joint_nees", ".2f"), ("reference_joint_nees", ".2f"))
    lines = "".join(f"<tr><td>{html.escape(n)}</td>"
                    + "".join(f"<td class=num>{num(v[k], fmt)}</td>" for k, fmt in keys) + "</tr>"
                    for n, v in slam.items())
    return ("<h2>The map (SLAM scenarios, seed means)</h2><table><thead><tr><th>scenario</th><th>ATE [m]</th>"
            f"<th>{SLAM_REFERENCE_SPEC} ATE</th><th>map GOSPA [m]</th><th>{SLAM_REFERENCE_SPEC} GOSPA</th>"
            "<th>landmarks</th><th>missed</th><th>false</th><th>joint NEES</th>"
            f"<th>{SLAM_REFERENCE_SPEC} joint NEES</th></tr></thead><tbody>{lines}</tbody></table>")


def write_outputs(board: dict[str, Any], out: Path) -> list[Path]:
    """``grade.csv``, ``grade.html``, ``grade.json`` (the rows without the plots), a page per
    student (``students/``), the logs (``logs/``), with pseudonyms ``pseudonyms.csv``, and
    the grade's secret in ``grade.secret`` (:data:`SECRET_FILE`, the owner's only; never in
    ``grade.json``, which names it by its fingerprint) in ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    if board.get("secret"):
        write_secret(str(board["secret"]), out / SECRET_FILE)
    logs = board.get("logs") or {}
    shown = _shown(board)
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
            w = csv.writer(fh)
            w.writerow(("pseudonym", "student", "file"))
            for r in board["rows"]:
                w.writerow((shown[r["student"]], r["student"], r["file"]))
    doc = {k: v for k, v in board.items() if k not in ("rows", "logs", "secret")}
    doc["rows"] = [{k: v for k, v in r.items() if k != "plot"} for r in board["rows"]]
    write_text_atomic(out / "grade.json", json.dumps(doc, indent=1, default=float), error=GradeError)
    return [write_csv(board, out / "grade.csv"), write_html(board, out / "grade.html"),
            out / "grade.json"]


__all__ = ["GradeConfig", "GradeError", "Student", "Task", "TaskResult", "find_class",
           "find_students", "grade", "load_config", "rank_key", "run_task", "run_tasks",
           "write_csv", "write_html", "write_outputs"]

