"""The Monte Carlo sweep over seeds (:func:`run_monte_carlo`, :func:`run_team_monte_carlo`):
runs spread over local processes or Dask tasks, results identical to a single process.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from itertools import pairwise
from typing import Any

from beacon_sim.core.scenario import Scenario, TeamScenario
from beacon_sim.evaluation.cluster import dask_workers, init_worker, on_dask
from beacon_sim.evaluation.montecarlo.batched import batch_reason, batch_task
from beacon_sim.evaluation.montecarlo.in_process import one_run, team_one_run
from beacon_sim.evaluation.montecarlo.records import RunOutput, TeamRunOutput
from beacon_sim.hosting.runner import HEADLESS_STEP_LIMIT_S
from beacon_sim.runs.progress import Progress


def _task(args) -> RunOutput:
    return one_run(*args)


def _task_group(group: list[Any]) -> list[RunOutput]:
    """Several runs in one Dask task, in order (each as :func:`_task`: the same results)."""
    return [one_run(*args) for args in group]


#: How many tasks each Dask worker gets on the per-run path: runs are grouped into about
#: this many tasks a worker (fewer tasks, less scheduling and serialisation; enough of them
#: that one slow group does not leave the other workers idle long).
TASKS_PER_DASK_WORKER = 3

#: The most run-steps one batch of the batched path holds (:func:`batch_size`): a batch keeps
#: every run's estimates (mean and covariance, 96 bytes a step per filter) until it ends, so
#: a thousand runs go as batches of a hundred or so, not as one.
BATCH_RUN_STEPS = 20_000


def batch_size(steps: int) -> int:
    """How many runs of ``steps`` steps one batch takes: 8 to 256, about ``BATCH_RUN_STEPS``
    run-steps (the results do not depend on it: a run's numbers never depend on its batch)."""
    return max(8, min(256, BATCH_RUN_STEPS // max(steps, 1)))


def default_jobs() -> int:
    """All the cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:
        return max(1, os.cpu_count() or 1)


def run_monte_carlo(scenario: Scenario, specs: list[str], runs: int, seed: int = 0,
                    duration: float | None = None, jobs: int | None = None,
                    params: dict[str, dict[str, Any]] | None = None,
                    progress: bool | None = None,
                    on_run: Callable[[RunOutput], None] | None = None,
                    batch: bool | None = None,
                    run_limit_s: float | None = None,
                    scheduler: Any = None, keep_runs: bool = True) -> list[RunOutput]:
    """``runs`` runs with seeds ``seed, seed + 1, ...``; returns them in seed order.

    ``on_run(run)`` is called with each run as it ends (in the order they end; ``run.index``
    says which it is); ``keep_runs`` False returns none of them (an empty list), so that a
    caller which reduces each run in ``on_run`` (``summary.Evaluation``) holds no run's
    arrays.

    ``scheduler``: None runs on ``jobs`` local processes; a Dask scheduler's address
    (``tcp://host:8786``), a ``dask.distributed`` Client or cluster runs the same tasks
    there (:func:`on_dask`), with the same results bit for bit.

    ``run_limit_s`` [s]: each filter's time limit per run (:func:`one_run`; the batched
    built-in filters have none).

    ``jobs`` processes (default: all cores; 1 runs in this process). The result does not
    depend on ``jobs`` except for the cost figures (``step_ns``).

    ``batch``: None batches the filters across runs (:func:`batch_runs`, one batch of
    contiguous runs per job) when every filter has a batched form and no parameter it
    does not support is set; False forces one run at a time; True insists on batching
    (ValueError when it is not possible).
    """
    duration = scenario.duration if duration is None else duration
    jobs_given = jobs
    jobs = default_jobs() if jobs is None else max(1, int(jobs))
    jobs = min(jobs, runs)
    params = params or {}
    if progress is None:  # a bar on a terminal, periodic lines in a log (runs/progress.py)
        progress = True
    bar = Progress(runs, f"eval {scenario.name}", progress)
    out: list[RunOutput | None] = [None] * runs
    if batch is not False:
        why = batch_reason(scenario, list(specs), params)
        if why is not None and batch:
            raise ValueError(f"cannot batch: {why}")
        batch = why is None
    if batch:
        if scheduler is not None and jobs_given is None:  # one batch per Dask worker
            jobs = min(runs, max(1, dask_workers(scheduler)))
        bounds = [round(k * runs / jobs) for k in range(jobs + 1)]
        size = batch_size(round(duration / scenario.dt))
        chunks = [list(range(a, b))[i:i + size] for a, b in pairwise(bounds) if b > a
                  for i in range(0, b - a, size)]
        btasks = [(scenario, list(specs), params, [seed + i for i in c], duration, c, 0) for c in chunks]

        def collect(done: list[RunOutput]) -> None:
            for r in done:
                if keep_runs:
                    out[r.index] = r
                bar.advance()
                if on_run:
                    on_run(r)

        if scheduler is not None:
            on_dask(scheduler, batch_task, btasks, lambda _i, done: collect(done))
        elif jobs == 1 or len(btasks) == 1:
            for bt in btasks:
                collect(batch_task(bt))
        else:
            with ProcessPoolExecutor(max_workers=min(jobs, len(btasks)), initializer=init_worker) as pool:
                pending = {pool.submit(batch_task, bt) for bt in btasks}
                for fut in as_completed(pending):
                    pending.discard(fut)   # dropped once taken: no finished batch is held
                    collect(fut.result())
        return [o for o in out if o is not None]
    tasks = [(scenario, list(specs), params, seed + i, duration, i, i == 0, run_limit_s)
             for i in range(runs)]
    if scheduler is not None:
        # a few runs a task (TASKS_PER_DASK_WORKER tasks a worker): the scenario is sent,
        # and the task scheduled, once per group instead of once per run
        size = -(-runs // (TASKS_PER_DASK_WORKER * max(1, dask_workers(scheduler))))
        groups = [list(range(a, min(a + size, runs))) for a in range(0, runs, size)]

        def group_done(k: int, rs: list[RunOutput]) -> None:
            for i, r in zip(groups[k], rs, strict=True):
                if keep_runs:
                    out[i] = r
                bar.advance()
                if on_run:
                    on_run(r)

        on_dask(scheduler, _task_group, [[tasks[i] for i in g] for g in groups], group_done)
    elif jobs == 1:
        for i, t in enumerate(tasks):
            run = _task(t)
            if keep_runs:
                out[i] = run
            bar.advance()
            if on_run:
                on_run(run)
    else:
        with ProcessPoolExecutor(max_workers=jobs, initializer=init_worker) as pool:
            futures = {pool.submit(_task, t): i for i, t in enumerate(tasks)}
            for done in as_completed(futures):
                run = done.result()
                i = futures.pop(done)   # dropped once taken: no finished run is held
                if keep_runs:
                    out[i] = run
                bar.advance()
                if on_run:
                    on_run(run)
    return [o for o in out if o is not None]


def _team_task(args) -> TeamRunOutput:
    return team_one_run(*args)


def run_team_monte_carlo(team: TeamScenario, specs: list[str], runs: int, seed: int = 0,
                         duration: float | None = None, jobs: int | None = None,
                         params: dict[str, dict[str, Any]] | None = None,
                         step_limit_s: float | None = HEADLESS_STEP_LIMIT_S,
                         run_limit_s: float | None = None) -> list[TeamRunOutput]:
    """``runs`` runs of ``team`` with seeds ``seed, seed + 1, ...`` on ``jobs`` processes
    (default: all cores; 1 runs here); returned in seed order. Limits: see :func:`team_one_run`."""
    duration = team.duration if duration is None else duration
    jobs = min(default_jobs() if jobs is None else max(1, int(jobs)), runs)
    tasks = [(team, list(specs), params or {}, seed + i, duration, i, step_limit_s, run_limit_s)
             for i in range(runs)]
    if jobs == 1:
        return [_team_task(t) for t in tasks]
    with ProcessPoolExecutor(max_workers=jobs, initializer=init_worker) as pool:
        return list(pool.map(_team_task, tasks))
