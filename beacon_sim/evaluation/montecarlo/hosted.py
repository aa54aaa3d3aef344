"""Runs of a filter hosted in a child process of its own (a file, a module, an entry
point): fed through the hosting layer's client (:mod:`beacon_sim.hosting.client`) and
scored here as :func:`~beacon_sim.evaluation.montecarlo.in_process.one_run` scores them
(:func:`isolated_run`, :func:`isolated_runs`, :func:`hosted_runs`,
:func:`run_monte_carlo_isolated`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from beacon_sim.core.files import MAX_SOURCE_BYTES, read_user_bytes
from beacon_sim.core.scenario import Scenario
from beacon_sim.evaluation.cluster import on_dask
from beacon_sim.evaluation.metrics import nis_batch
from beacon_sim.evaluation.montecarlo.records import FilterRun, RunOutput, finish_filter
from beacon_sim.evaluation.montecarlo.simulation import SimulatedRun, simulate_run
from beacon_sim.evaluation.montecarlo.sweep import run_monte_carlo
from beacon_sim.hosting.loading import (
    FilterLoadError,
    filter_display_name,
    filter_names,
)


def _slot(sr: SimulatedRun, name: str, params: dict[str, Any] | None, frames: list[bytes] | None = None,
          ticks: int | None = None) -> Any:
    """The :class:`~beacon_sim.hosting.feed.Slot` of a hosted filter ``name`` on ``sr``
    (:func:`~beacon_sim.hosting.client.hosted_slot`)."""
    from beacon_sim.hosting.client import hosted_slot

    return hosted_slot(sr.scenario, sr.stream_key, name, params, sr.frames if frames is None else frames,
                       ticks)


def _padded(a: np.ndarray, T: int) -> np.ndarray:
    """``a`` (rows, ...) with NaN rows after its own up to ``T`` rows (a run that stopped early)."""
    if a.shape[0] >= T:
        return a
    return np.concatenate([a, np.full((T - a.shape[0], *a.shape[1:]), np.nan)])


def _run_of(fed: Any, k: int, sr: SimulatedRun, name: str, keep_means: bool) -> RunOutput:
    """Slot k of a fed batch scored as :func:`one_run` scores the filter on ``sr``."""
    T = len(sr.frames)
    means, covs = _padded(fed.means(k)[:T], T), _padded(fed.covs(k)[:T], T)
    pm, pc = np.full((len(sr.records), 3), np.nan), np.full((len(sr.records), 3, 3), np.nan)
    ticks = np.flatnonzero(fed.has_prior[:T, k])
    rows = sr.record_index[ticks]
    pm[rows] = fed.prior_means(k)[ticks]
    pc[rows] = fed.prior_covs(k)[ticks]
    out = _hosted_output(sr, name, means, covs, pm, pc, fed.done(k), fed.failed[k],
                         int(fed.walls[:, k].sum()), keep_means)
    fr = out.filters[name]
    fr.landmarks = fed.maps[k] if fed.failed[k] is None else None
    fr.joint = fed.joints[k] if fed.failed[k] is None else None
    return out


def isolated_run(child: Any, sr: SimulatedRun, run_limit_s: float | None, keep_means: bool = False,
                 other: bool = False, global_seed: int | None = None,
                 ticks: int | None = None, name: str | None = None,
                 params: dict[str, Any] | None = None) -> tuple[RunOutput, dict[str, Any]]:
    """:func:`one_run` of the filter in ``child`` (a :class:`~beacon_sim.hosting.isolated.FilterChild`)
    on the simulated run ``sr``: the same numbers bit for bit, the truth never sent (a batch
    of one, :func:`~beacon_sim.hosting.feed.feed_batch`). Returns the run and what the child
    reported (``np_global`` / ``py_global``: the filter drew from the global generators;
    ``failed_child``: the child must not be reused). ``other``: the run with its readings
    drawn again (a probe, not a graded run); ``global_seed``: the global RNGs' seed
    (default derived from the run's key and the name, never the seed); ``ticks``: only the
    first ``ticks`` ticks (a probe; ``report["means"]`` holds its estimates); ``name``: the
    filter's name in the run (default its class's: its random generator's stream);
    ``params``: its parameters (default the scenario's ``[filters.NAME]``)."""
    from beacon_sim.hosting.client import feed_batch

    name = name or child.class_name
    frames = sr.frames_other if other and sr.frames_other is not None else sr.frames
    slot = _slot(sr, name, params, frames, ticks)
    fed = feed_batch(child, [slot], run_limit_s, sr.global_seed(name) if global_seed is None else global_seed)
    report = dict(fed.report)
    done = fed.done(0)
    theta = fed.means(0)[:done, 2]
    report["heading_unwrapped"] = bool(np.any(~((theta >= -np.pi) & (theta < np.pi))))
    if ticks is not None:  # a probe: its estimates only
        T = slot.ticks
        report["means"] = fed.means(0)[:T]
        report["failed"] = fed.failed[0]
        return RunOutput(sr.index, sr.seed, sr.truth[:T + 1], sr.controls[:T], sr.kidnapped[:T],
                         sr.truth_checksum), report
    return _run_of(fed, 0, sr, name, keep_means), report


def _hosted_output(sr: SimulatedRun, name: str, means: np.ndarray, covs: np.ndarray, pm: np.ndarray,
                   pc: np.ndarray, done: int, failed: str | None, ns: int, keep_means: bool) -> RunOutput:
    """A hosted filter's run scored against the truth of ``sr`` as :func:`one_run` scores it:
    its estimates ``means`` (T, 3) and ``covs`` (T, 3, 3), its estimates after predict on the
    ticks with readings ``pm``, ``pc`` (for the NIS), ``done`` steps, ``ns`` [ns] of cost."""
    scenario = sr.scenario
    out = RunOutput(sr.index, sr.seed, sr.truth, sr.controls, sr.kidnapped, sr.truth_checksum)
    n_rec = len(sr.records)
    good = np.all(np.isfinite(pm), axis=1) & np.all(np.isfinite(pc), axis=(1, 2))
    n_good = int(np.argmin(good)) if not good.all() else n_rec
    sensors = {s.name: s for s in scenario.model_sensors}
    with np.errstate(all="ignore"):
        nis_sum, nis_dof = nis_batch(sr.records[:n_good], pm[:n_good], pc[:n_good], sensors,
                                     scenario.world)
    out.filters[name] = finish_filter(means, covs, sr.truth, done, failed, nis_sum, nis_dof, ns,
                                      keep_means)
    return out


def isolated_runs(child: Any, sims: list[SimulatedRun], run_limit_s: float | None,
                  name: str | list[str] | None = None,
                  params: dict[str, Any] | list[dict[str, Any]] | None = None,
                  probe_ticks: int | None = None,
                  restart: Any = None) -> tuple[list[RunOutput], dict[str, Any]]:
    """:func:`isolated_run` of every run of ``sims`` at once: one filter per run in the
    child, one exchange per tick carrying every run's control, dt and readings and bringing
    back every estimate (the pipe's round trip paid once per tick, not once per run;
    :func:`~beacon_sim.hosting.feed.feed_batch`). Each filter is built and fed exactly as
    alone, with its own CPU-time budget, failure and cost, so a filter that does not draw
    from the global generators gives the numbers of :func:`isolated_run` bit for bit; a
    filter that fails fails its own run only, a child that dies fails every run still
    going with the reason. The runs must have the same number of ticks. Returns the runs
    (each keeps its means when ``sr.index == 0``) and what the child reported
    (``np_global`` / ``py_global``: drew from the global generators, whose stream is then
    shared by the batch: rerun alone; ``failed_child``: do not reuse).

    ``probe_ticks``: the probes of ``sims[0]`` ride along, on its first ``probe_ticks``
    ticks (:func:`~beacon_sim.hosting.feed.probe_slots`: fed again; and its extra run,
    ``sims[0].extra``, fed its readings and its readings drawn again), every slot in an
    order drawn from the run's key, so that the child cannot tell a probe from a scored
    run; their findings are in ``report["probes"]``
    (:class:`~beacon_sim.hosting.feed.ProbeFindings`).

    ``name`` and ``params`` may be lists, one per run (the robots of a team scenario: each
    robot's copy its own name, so its own random stream); the runs' records are keyed by
    the first name.

    ``restart`` (stops the child and returns a fresh one): each run's memory limit is its
    own; a batch whose runs may have run out of the memory they shared is fed again one run
    per fresh child (:func:`~beacon_sim.hosting.feed.feed_batch`)."""
    from beacon_sim.hosting.client import feed_batch, judge_probes, probe_slots, slot_order

    R = len(sims)
    names = list(name) if isinstance(name, list) else [name or child.class_name] * R
    run_params: list[dict[str, Any] | None] = list(params) if isinstance(params, list) else [params] * R
    name = names[0]
    T = len(sims[0].frames)
    if any(len(sr.frames) != T for sr in sims):
        raise ValueError("isolated_runs: the runs of a batch must have the same number of ticks")
    slots = [_slot(sr, names[k], run_params[k]) for k, sr in enumerate(sims)]
    probes: dict[str, int] = {}
    order = None
    if probe_ticks is not None:
        ex = sims[0].extra
        extra = ((_slot(ex, names[0], run_params[0]), ex.frames_other)
                 if ex is not None and ex.frames_other is not None else None)
        for what, slot in probe_slots(0, slots[0], extra, probe_ticks):
            probes[what] = len(slots)
            slots.append(slot)
        order = slot_order(sims[0].stream_key, len(slots))
    fed = feed_batch(child, slots, run_limit_s, sims[0].global_seed(names[0]), order, restart=restart)
    report = dict(fed.report)
    theta = np.concatenate([fed.means(k)[:fed.done(k), 2] for k in range(R)])
    report["heading_unwrapped"] = bool(np.any(~((theta >= -np.pi) & (theta < np.pi))))
    if probes:
        ex = sims[0].extra
        within = ex is not None and ex.readings_within(min(probe_ticks or 0, len(ex.frames)))
        report["probes"] = judge_probes(fed, 0, probes, within)
    return [_run_of(fed, k, sr, name, sr.index == 0) for k, sr in enumerate(sims)], report


def run_monte_carlo_isolated(scenario: Scenario, specs: list[str], runs: int, seed: int = 0,
                             duration: float | None = None, jobs: int | None = None,
                             params: dict[str, dict[str, Any]] | None = None,
                             run_limit_s: float | None = None, sandbox: str = "auto",
                             memory_gb: float = 4.0, log_dir: Any = None,
                             batch: bool | None = None, scheduler: Any = None) -> list[RunOutput]:
    """:func:`run_monte_carlo` with every filter file (``path.py:Class``), module filter
    (``pkg.mod:Class``) and entry-point filter in a child process of its own
    (:mod:`beacon_sim.hosting.isolated`, :func:`~beacon_sim.hosting.sources.hosted_source`):
    the built-in filters run as before (the same numbers), each hosted filter's runs are
    streamed from simulations made here, and the records are merged in ``specs`` order.
    The same figures as in process, bit for bit, for a filter that does not reach for the
    truth. ``scheduler`` (as for :func:`run_monte_carlo`): the built-ins' runs and one task
    per hosted filter (its child started on the worker; a file is sent with the task, a
    module must be importable there) run on Dask."""
    import tempfile
    from pathlib import Path

    from beacon_sim.hosting.containment import resolve_sandbox
    from beacon_sim.hosting.loading import merged_params
    from beacon_sim.hosting.sources import hosted_source

    duration = scenario.duration if duration is None else duration
    params = params or {}
    names = filter_names(specs)
    hosted = {spec: hosted_source(spec) for spec in specs}
    inside = [s for s in specs if hosted[s] is None]
    # Not batched: the built-ins' numbers stay those of a run beside a file filter in process
    # (a batched run differs in the last bits).
    base = run_monte_carlo(scenario, inside, runs, seed, duration, jobs, params, progress=False,
                           batch=False if len(inside) < len(specs) else batch,
                           run_limit_s=run_limit_s, scheduler=scheduler) if inside else None
    sims = [simulate_run(scenario, seed + i, duration, i) for i in range(runs)]
    level = resolve_sandbox(sandbox) if scheduler is None else sandbox  # on Dask: the worker's
    logs = Path(log_dir) if log_dir is not None else Path(tempfile.mkdtemp(prefix="beacon-sim-eval-"))
    tasks: list[HostedTask] = []
    task_names: list[str] = []
    for spec, name in zip(specs, names, strict=True):
        where = hosted[spec]
        if where is None:
            continue
        source, cls = where
        shipped: Any = source
        if scheduler is not None:  # a file travels with its task; a module is found there
            shipped = ((source.name, read_user_bytes(source, what="filter file", cap=MAX_SOURCE_BYTES,
                                                      error=FilterLoadError))
                       if isinstance(source, Path) else source.module)
        fp = merged_params(spec, scenario, params.get(filter_display_name(spec)))
        tasks.append(HostedTask(shipped, cls, name, fp, sims, run_limit_s, level, memory_gb,
                                None if scheduler is not None else str(logs / f"{name}.log")))
        task_names.append(name)
    isolated: dict[str, list[FilterRun]] = {}
    if scheduler is not None:
        on_dask(scheduler, hosted_runs, tasks,
                lambda i, recs: isolated.__setitem__(task_names[i], recs))
    else:
        for name, t in zip(task_names, tasks, strict=True):
            isolated[name] = hosted_runs(t)
    result = []
    for i, sr in enumerate(sims):
        run = RunOutput(sr.index, sr.seed, sr.truth, sr.controls, sr.kidnapped, sr.truth_checksum)
        for name in names:
            run.filters[name] = isolated[name][i] if name in isolated else base[i].filters[name]  # type: ignore[index]
        result.append(run)
    return result


@dataclass
class HostedTask:
    """Every run of one hosted filter (what :func:`hosted_runs` does, a Dask task of
    :func:`run_monte_carlo_isolated`).

    Attributes
    ----------
    source : Path, (str, bytes), ModuleSource or str
        The filter's file, the file's name and bytes (sent to a Dask worker), its module's
        package (:class:`~beacon_sim.hosting.containment.ModuleSource`), or a module's name
        (found on the worker).
    class_name : str or None
        Its class (None: the file's choice).
    name : str
        Its name in the run (its random generator's stream).
    params : dict
        Its parameters (the scenario's ``[filters.NAME]`` and ``--set`` values).
    sims : list of SimulatedRun
        The runs, simulated once by the caller.
    run_limit_s : float or None
        Its CPU-time limit per run [s].
    sandbox : str
        The containment level (``auto`` resolved where the task runs).
    memory_gb : float
        Its child's memory limit [GB].
    log : str or None
        Its child's log (None: a temporary one).
    """

    source: Any
    class_name: str | None
    name: str
    params: dict[str, Any]
    sims: list[SimulatedRun]
    run_limit_s: float | None
    sandbox: str
    memory_gb: float
    log: str | None


def hosted_runs(task: HostedTask) -> list[FilterRun]:
    """Every run of one hosted filter (``task``), in a child of its own
    (:class:`~beacon_sim.hosting.client.ChildSession`: a new one after a child that must not
    be reused): a file's runs fed together, unless it draws from the global generators
    (their stream would be shared), then one at a time."""
    import shutil
    import tempfile
    from pathlib import Path

    from beacon_sim.hosting.client import ChildSession
    from beacon_sim.hosting.containment import Limits, module_source, resolve_sandbox
    from beacon_sim.hosting.loading import FilterLoadError

    sims, name, run_limit_s = task.sims, task.name, task.run_limit_s
    source = task.source
    tmp = Path(tempfile.mkdtemp(prefix="beacon-sim-hosted-"))
    try:
        if isinstance(source, tuple):
            file = tmp / Path(source[0]).name
            file.write_bytes(source[1])
            source = file
        elif isinstance(source, str):
            found = module_source(source)
            if found is None:
                raise FilterLoadError(f"{source}: cannot import module {source!r} on this Dask worker")
            source = found
        log_path = Path(task.log) if task.log is not None else tmp / "log.txt"
        limits = Limits(memory_gb=task.memory_gb,
                        cpu_s=None if run_limit_s is None else run_limit_s * len(sims) * 1.5 + 60)
        timeout = max(60.0, 5 * (run_limit_s or 60.0))
        with ChildSession(source, task.class_name, log_path, resolve_sandbox(task.sandbox), limits,
                          timeout) as session:
            if isinstance(source, Path) and len({len(sr.frames) for sr in sims}) == 1:
                child = session.child()
                if child is not None:
                    outs, rep = isolated_runs(child, sims, run_limit_s, name=name, params=task.params)
                    session.stop()
                    if not (rep.get("np_global") or rep.get("py_global")):
                        return [out.filters[name] for out in outs]
            records: list[FilterRun] = []
            for sr in sims:
                child = session.child()
                if child is None:
                    T = len(sr.frames)
                    records.append(finish_filter(np.full((T, 3), np.nan), np.full((T, 3, 3), np.nan),
                                                 sr.truth, 0, session.load_problem or "failed", 0.0, 0, 0,
                                                 sr.index == 0))
                    continue
                out, rep = isolated_run(child, sr, run_limit_s, keep_means=sr.index == 0, name=name,
                                        params=task.params)
                records.append(out.filters[name])
                if rep.get("failed_child"):
                    session.stop()
            return records
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
