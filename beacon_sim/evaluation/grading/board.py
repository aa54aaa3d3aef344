"""``grade()``: the whole class graded, simulations made once, each student hosted, scored
and ranked, as a typed :class:`GradeResult`.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from beacon_sim.core.files import (
    MAX_SOURCE_BYTES,
    read_user_bytes,
)
from beacon_sim.core.scenario import (
    Scenario,
    TeamScenario,
    is_team_scenario,
    load_scenario,
    load_team_scenario,
)
from beacon_sim.evaluation.grading.cache import run_cached, students_cannot_write_here
from beacon_sim.evaluation.grading.config import GradeConfig, GradeError, scenario_labels
from beacon_sim.evaluation.grading.roster import find_students
from beacon_sim.evaluation.grading.scoring import (
    add_findings,
    add_rubric,
    is_scan_scenario,
    is_slam_scenario,
    rank_key,
    score_scan_reference,
    score_slam_reference,
    score_together,
    student_row,
    team_figures,
)
from beacon_sim.evaluation.grading.secret import check_secret, new_secret, secret_fingerprint
from beacon_sim.evaluation.grading.students import StudentJob, TeamSimulated, simulate_team_run
from beacon_sim.evaluation.grading.tasks import REFERENCE, REFERENCE_SPEC, Task, TaskResult, run_tasks
from beacon_sim.evaluation.montecarlo import (
    SimulatedRun,
    TeamRunOutput,
    simulate_run,
)
from beacon_sim.hosting.containment import SandboxError, bwrap_problem, resolve_sandbox, unisolated_warning


@dataclass
class GradeResult:
    """A graded class: what :func:`grade` returns and
    :func:`~beacon_sim.evaluation.grading.outputs.write_outputs` writes
    (:meth:`document` is ``grade.json``'s content, with the plots, logs and secret).

    Attributes
    ----------
    rows : list of dict
        One row per student, in rank order (``rank``, ``student``, the figures, ``failures``,
        ``flags``...; docs/grading.md, "What the leaderboard shows").
    config : dict
        The :class:`~beacon_sim.evaluation.grading.config.GradeConfig` graded with, as a dict.
    wall_s : float
        The grade's wall time [s].
    students, runs_per_student : int
        How many files were graded, and runs each (scenarios x seeds).
    reference, slam_reference, scan_reference : dict
        The built-in filters' figures beside the students: per team scenario (independent
        EKF), SLAM scenario (EKF-SLAM) and scan scenario (mcl).
    sandbox : str
        How the students' children were contained (``bwrap`` or ``process``).
    isolated : bool
        Every student ran in a child process of its own (always True).
    team_in_process : list
        Kept empty (``grade.json``'s field).
    cached_students : list of str
        The students whose results came from the cache.
    secret : str
        The grade's secret (hex): kept in ``grade.secret``, never in ``grade.json``.
    secret_sha256 : str
        Its fingerprint (:func:`~beacon_sim.evaluation.grading.secret.secret_fingerprint`).
    child_cpu_s : float
        What the students' children said they used [s] (their own word: cost figures only).
    logs : dict
        Each student's log (stdout and stderr of its child).
    not_isolated : str
        At the process level: what a file could do to its classmates and the grader (the
        page and the terminal say it); empty under bubblewrap.
    """

    rows: list[dict[str, Any]]
    config: dict[str, Any]
    wall_s: float
    students: int
    runs_per_student: int
    reference: dict[str, Any]
    slam_reference: dict[str, Any]
    scan_reference: dict[str, Any]
    sandbox: str
    isolated: bool
    team_in_process: list[Any]
    cached_students: list[str]
    secret: str
    secret_sha256: str
    child_cpu_s: float
    logs: dict[str, str]
    not_isolated: str = ""

    def document(self) -> dict[str, Any]:
        """The leaderboard as one document (its fields, in order, not copied): what the CSV
        and HTML writers read and ``grade.json`` holds (less the plots, logs and secret)."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}


def grade(folder: str | Path, config: GradeConfig = GradeConfig(), jobs: int | None = None,  # noqa: B008 - frozen
          scheduler: Any = None, progress: Callable[[int, int], None] | None = None,
          cache: str | Path | None = None, secret: bytes | None = None) -> GradeResult:
    """Grade every filter file in ``folder``; returns the leaderboard (:class:`GradeResult`:
    ``rows`` in rank order, ``config``, ``wall_s``, ``sandbox``, ``logs``, ``secret``...)
    that :func:`~beacon_sim.evaluation.grading.outputs.write_outputs` writes.

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
    if sandbox == "process" and len(students) > 1 and not config.allow_unisolated:
        raise GradeError("grading a class at the process level: the students' processes are not "
                         "isolated from each other (bubblewrap " + (bwrap_problem() or "was not chosen")
                         + "); install bubblewrap, or say allow_unisolated = true (--allow-unisolated) "
                         "to grade anyway (docs/threat-model.md)")
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
                               config.memory_limit_gb, sandbox, team_sims, config.total_time_s,
                               config.disk_limit_mb)
                    for st in students if st.spec and (sims or team_sims)]
    if cache is not None and not students_cannot_write_here(sandbox):
        cache = None  # a child running as this user could plant a pickle: no cache
    done_students, cached = run_cached(student_jobs, jobs, scheduler, progress,
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
            ref = team_figures(scenarios[name], runs)  # type: ignore[arg-type]
            reference[name] = {k: v for k, v in ref.items() if k != "curve"}
    found = {sr.student: sr for sr in done_students}
    scored = score_together(scenarios, single, by, students, len(config.seeds))
    slam_names = [n for n in single if is_slam_scenario(scenarios[n])]
    slam_reference = score_slam_reference(sims, slam_names)
    scan_reference = score_scan_reference(scenarios, [n for n in single if is_scan_scenario(scenarios[n])],
                                     config)
    for st in students:
        done = found.get(st.name)
        row = student_row(st, config, scenarios, by, n_runs, reference, scored, slam_reference,
                           done.findings.get("probe_failures") or () if done is not None else ())
        for name, ref in scan_reference.items():  # a scan assignment: the row beside mcl's
            got = scored.get((st.name, name))
            mine = got[0].get("pos_rmse_m") if got is not None and not row["failed_runs"] else None
            theirs = ref["pos_rmse_m"]
            row.setdefault("scan", {})[name] = {
                "pos_rmse_m": mine, "reference_pos_rmse_m": theirs,
                "over_reference": mine / theirs if mine is not None and theirs else None}
        add_findings(row, found.get(st.name))
        add_rubric(row, config)
        rows.append(row)
    rows.sort(key=rank_key)
    for k, row in enumerate(rows, 1):
        row["rank"] = k
    return GradeResult(
        rows=rows, config=asdict(config), wall_s=time.perf_counter() - t0, students=len(students),
        runs_per_student=n_runs, reference=reference, slam_reference=slam_reference,
        scan_reference=scan_reference, sandbox=sandbox, isolated=True, team_in_process=[],
        cached_students=cached, secret=secret.hex(), secret_sha256=secret_fingerprint(secret),
        child_cpu_s=sum(float(sr.findings.get("child_cpu_s", 0.0)) for sr in done_students),
        logs={sr.student: sr.log for sr in done_students},
        not_isolated=unisolated_warning() if sandbox == "process" else "")
