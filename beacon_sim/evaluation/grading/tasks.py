"""The runs graded in the grader's own processes or on Dask (the built-in reference filters
beside the students): a :class:`Task` per (filter, scenario, seed), each a
:func:`~beacon_sim.evaluation.montecarlo.one_run` with a per-run time limit
(:func:`run_task`, :func:`run_tasks`).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from beacon_sim.core.scenario import is_team_scenario, load_scenario, load_team_scenario
from beacon_sim.evaluation.montecarlo import (
    RunOutput,
    TeamRunOutput,
    default_jobs,
    init_worker,
    on_dask,
    one_run,
    team_one_run,
)
from beacon_sim.hosting.team_specs import MEMBER_PREFIX

#: The student name of the built-in filter graded beside the students on team scenarios.
REFERENCE = "__reference__"
#: Its spec: every robot's own built-in EKF (the ``independent`` team filter).
REFERENCE_SPEC = "ekf"


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
