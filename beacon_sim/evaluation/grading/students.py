"""Each student's filter in a child process of its own, fed the runs the grader simulated
once (:func:`run_student`, :func:`run_students`): the scenario's seeds in one batch, the
probes riding along, a team scenario's robots fed together; the child is driven through
the hosting layer's one client (:class:`~beacon_sim.hosting.client.ChildSession`).
"""

from __future__ import annotations

import dataclasses
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from beacon_sim.core.scenario import TeamScenario
from beacon_sim.evaluation.grading.tasks import Task, TaskResult
from beacon_sim.evaluation.montecarlo import (
    RunOutput,
    SimulatedRun,
    TeamRunOutput,
    default_jobs,
    isolated_run,
    isolated_runs,
    on_dask,
)
from beacon_sim.hosting.client import ChildSession, FilterChild, step_request
from beacon_sim.hosting.containment import Limits
from beacon_sim.hosting.feed import LOG_BYTES as FEED_LOG_BYTES
from beacon_sim.hosting.feed import PROBE_TICKS as FEED_PROBE_TICKS
from beacon_sim.hosting.feed import PROBES, ProbeFindings, child_limits, metered_stop, reply_timeout

#: How many ticks the probes of a student's filter run (the first scenario and seed; see
#: :mod:`beacon_sim.hosting.feed`): the run fed again (is it deterministic?), the run with
#: its readings drawn again (does it use them?) and that fed again. LOG_BYTES: the most of
#: a student's log the leaderboard keeps and links [bytes].
PROBE_TICKS = FEED_PROBE_TICKS
LOG_BYTES = FEED_LOG_BYTES


@dataclass
class TeamSimulated:
    """One team (scenario, seed) simulated once by the grader: each robot's run
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
    #: The student's total wall time [s] (None: :func:`total_time_limit`'s default).
    total_time_s: float | None = None
    #: What the student's process may write [MB] (its folder, /tmp, /dev/shm).
    disk_limit_mb: float = 64.0


@dataclass
class StudentResult:
    """One student's runs (task order), the findings of the probes and the child's log."""

    student: str
    results: list[TaskResult]
    findings: dict[str, Any]
    log: str
    sandbox: str


def total_time_limit(job: StudentJob) -> float:
    """A student's total wall time [s]: the job's, or by default twice every run's CPU
    budget (the scored runs, the probes and team robots) and two minutes for starting."""
    if job.total_time_s is not None:
        return job.total_time_s
    runs = len(job.sims) + len(PROBES) + sum(len(ts.robots) for ts in job.team_sims)
    return 2.0 * runs * job.time_limit + 120.0


def total_time_text(seconds: float) -> str:
    """The words of a run stopped by the student's total wall time."""
    return (f"the student's total time limit: {seconds:g} s of wall time for all its runs "
            "(total_time_s) was used up")


def _limits(job: StudentJob) -> Limits:
    runs = len(job.sims) + len(PROBES) + sum(len(ts.robots) for ts in job.team_sims)
    return child_limits(job.time_limit, runs, job.memory_limit_gb, job.disk_limit_mb)


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
        total = total_time_limit(job)
        out_of_time = threading.Event()

        def expire() -> None:  # the student's total wall time is up: no new child, stop this one
            out_of_time.set()
            session.load_problem = total_time_text(total)
            current = session.current
            if current is not None:
                current.kill()

        timer = threading.Timer(total, expire)
        timer.daemon = True
        timer.start()

        def task(sr: SimulatedRun) -> Task:
            return Task(job.student, job.filename, sr.label, sr.seed, None, job.time_limit, sr.index)

        def started() -> FilterChild | None:
            nonlocal load_problem
            child = session.child()
            if child is not None and out_of_time.is_set():
                # the time ran out while it was starting (a loaded machine): expire() found
                # no child to stop then, so it is stopped now and its runs fail saying so
                child.kill()
            if child is not None:
                findings["form"] = session.form
            elif load_problem is None:
                load_problem = findings["load_problem"] = session.load_problem
            return child

        def stop() -> None:
            session.stop()
            findings["child_cpu_s"] = session.cpu_s

        def restart() -> FilterChild | str:  # a fresh child (a run alone: its own memory)
            stop()
            child = started()
            return child if child is not None else (load_problem or "the file did not load")

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
                                          probe_ticks=PROBE_TICKS if probing else None, restart=restart)
                if rep.get("failed_child") or rep.get("alone"):
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
            timer.cancel()
            stop()
        if out_of_time.is_set():
            findings["limits_hit"] = [total_time_text(total)]
            _blame_total_time([r for r in results if r is not None] + team_results, total_time_text(total))
        raw = log.read_bytes() if log.exists() else b""
        text = raw[:LOG_BYTES + 100].decode("utf-8", "replace")
        if len(raw) > LOG_BYTES + 100:
            text += f"\n[log cut at {LOG_BYTES} bytes]\n"
    findings["wall_s"] = time.perf_counter() - t_start
    return StudentResult(job.student, [r for r in results if r is not None] + team_results, findings, text,
                         job.sandbox)


def _blame_total_time(results: list[TaskResult], why: str) -> None:
    """After the student's total time ran out: every run that failed (its child was
    stopped, or never started) says so, not what the stop looked like from inside."""
    for r in results:
        if r.run is None:
            r.problem = why
            continue
        frs = r.run.filters.values()
        for fr in (f for group in frs for f in (group if isinstance(group, list) else [group])):
            if fr.failed:
                fr.failed = why


def _run_team_batches(job: StudentJob, started: Callable[[], FilterChild | None],
                      stop: Callable[[], None], record_team: dict[str, Any]) -> list[TaskResult]:
    """The student's team runs: per team scenario, every robot of every seed fed
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
    upto = n
    if metered_stop(rep.get("failed")):  # the copy ran out of a metered budget: its tick is the meter's
        upto = int(np.argmax(np.isnan(rep["means"][:, 0]))) if np.isnan(rep["means"][:, 0]).any() else n
    deterministic = bool(np.array_equal(rep["means"][:upto], first[:upto], equal_nan=True))
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
