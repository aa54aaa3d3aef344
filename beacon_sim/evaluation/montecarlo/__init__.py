"""Monte Carlo runs: one simulated run per seed, every filter on exactly the same steps,
runs spread over processes with results identical to a single process.

Run ``i`` uses seed ``seed + i``; each run is built from its seed alone (design.md section
5), so the order in which processes finish changes nothing but the timing figures.

Two ways to drive the filters: :func:`one_run`, one run and every filter object on its
steps; :func:`batch_runs`, R runs together, each filter that has a batched form
(``filters.gaussian.measurements.BatchableFilter``: kf, ekf, ukf, dead reckoning) as one
object whose state is arrays (mean (R, 3), cov (R, 3, 3)), so one numpy call updates every
run instead of ~1 us of numpy overhead per 3x3 call per run (design.md section 9). The
filter modules hold both forms of their maths; here are only the simulations, the packing
of their readings (``SlotPacker``: slots fixed by the scenario, so a run's numbers never
depend on its batch) and the records.

A team scenario's runs (:func:`run_team_monte_carlo`) are each the one guarded headless run
over N robots (``runs.headless.run_headless``), reduced per robot to the single-robot records.

The package, one module per idea: ``records`` (what a run leaves), ``simulation`` (a run
simulated once for hosted filters), ``in_process`` (every filter object on a run's steps),
``batched`` (R runs as arrays), ``hosted`` (a filter in its child process), ``sweep``
(runs spread over processes or Dask); Dask itself is :mod:`beacon_sim.evaluation.cluster`.
The names below are its public API.
"""

from beacon_sim.evaluation.cluster import (
    DASK_LEAN_CONFIG,
    WORKER_MEMORY_GB,
    ClusterError,
    dask_client,
    dask_workers,
    init_worker,
    limit_worker_memory,
    on_dask,
)
from beacon_sim.evaluation.montecarlo.batched import batch_reason, batch_runs
from beacon_sim.evaluation.montecarlo.hosted import (
    HostedTask,
    hosted_runs,
    isolated_run,
    isolated_runs,
    run_monte_carlo_isolated,
)
from beacon_sim.evaluation.montecarlo.in_process import one_run, team_one_run
from beacon_sim.evaluation.montecarlo.records import FilterRun, RunOutput, TeamRunOutput, finish_filter, stack
from beacon_sim.evaluation.montecarlo.simulation import SimulatedRun, simulate_run, start_run
from beacon_sim.evaluation.montecarlo.sweep import (
    TASKS_PER_DASK_WORKER,
    default_jobs,
    run_monte_carlo,
    run_team_monte_carlo,
)
from beacon_sim.hosting.loading import filter_names

__all__ = ["DASK_LEAN_CONFIG", "TASKS_PER_DASK_WORKER", "WORKER_MEMORY_GB", "ClusterError", "FilterRun",
           "HostedTask", "RunOutput", "SimulatedRun", "TeamRunOutput", "batch_reason", "batch_runs",
           "dask_client", "dask_workers", "default_jobs", "filter_names", "finish_filter", "hosted_runs",
           "init_worker", "isolated_run", "isolated_runs", "limit_worker_memory", "on_dask", "one_run",
           "run_monte_carlo", "run_monte_carlo_isolated", "run_team_monte_carlo", "simulate_run",
           "stack", "start_run", "team_one_run"]
