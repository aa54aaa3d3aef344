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
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from itertools import pairwise
from typing import Any

import numpy as np

from beacon_sim.core.batch_simulation import BatchSimulation
from beacon_sim.core.files import MAX_SOURCE_BYTES, read_user_bytes
from beacon_sim.core.metrics import nees as nees_of
from beacon_sim.core.metrics import pose_errors
from beacon_sim.core.scenario import Scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.core.team_scenario import TeamScenario
from beacon_sim.core.threads import limit_blas_threads
from beacon_sim.evaluation.metrics import nis_batch
from beacon_sim.filters.base import Batchable, FilterError
from beacon_sim.filters.gaussian.measurements import BatchableFilter, SlotPacker, nis
from beacon_sim.hosting.guard import DIVERGED, MAX_COV, MAX_MEAN, NEES_NOT_FINITE, estimate_arrays
from beacon_sim.hosting.host import call_guarded
from beacon_sim.hosting.loading import (
    FilterLoadError,
    build_filter,
    filter_display_name,
    filter_names,
    load_filter_class,
)
from beacon_sim.hosting.runner import HEADLESS_STEP_LIMIT_S
from beacon_sim.hosting.watchdog import failure_line, is_filter_failure
from beacon_sim.runs.headless import run_headless
from beacon_sim.runs.progress import Progress


@dataclass
class FilterRun:
    """One filter in one run. Arrays have one row per step; rows after a failure are NaN.

    err : (T, 3) [m, m, rad] estimate - truth, heading wrapped.
    var : (T, 3) the diagonal of the filter's covariance.
    nees : (T,) ``e^T P^-1 e``.
    """

    err: np.ndarray
    var: np.ndarray
    nees: np.ndarray
    nis_sum: float
    nis_dof: int
    step_ns: int
    steps: int
    failed: str | None = None
    means: np.ndarray | None = None  # (T, 3), kept for the first run only (trajectory plot)
    #: A hosted SLAM filter's map after its last step: (ids (M,) or None, means (M, 2) [m],
    #: covs (M, 2, 2) [m^2]), judged as it came back (hosting/wire.py); None without a map.
    landmarks: tuple[np.ndarray | None, np.ndarray, np.ndarray] | None = None
    #: Its final ``joint()`` (mean (3 + 2M,), cov, landmark IDs (M,)), when it has one.
    joint: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None


@dataclass
class RunOutput:
    """One run: the truth, the commands, kidnaps, and each filter's record."""

    index: int
    seed: int
    truth: np.ndarray  # (T + 1, 3), row 0 = initial pose
    controls: np.ndarray  # (T, 2) [m/s, rad/s]
    kidnapped: np.ndarray  # (T,) bool
    truth_checksum: str
    filters: dict[str, FilterRun] = field(default_factory=dict)


def _check(means: np.ndarray, covs: np.ndarray) -> tuple[int, str | None]:
    """Index of the first unusable estimate and why, in the guard's words and by its rules
    (:func:`~beacon_sim.hosting.guard.validate_estimate`: non-finite, diverged, asymmetric
    or not PSD), so that ``eval`` and ``grade`` fail a filter where ``run`` does, and say
    the same (issue 37: they let a covariance grow to 1e100)."""
    n = means.shape[0]
    bad = ~(np.all(np.isfinite(means), axis=1) & np.all(np.isfinite(covs), axis=(1, 2)))
    first = int(np.argmax(bad)) if bad.any() else n
    if first < n:
        return first, "estimate() returned NaN or infinity"
    scale = np.maximum(np.max(np.abs(covs), axis=(1, 2)), 1e-12)
    huge = (scale > MAX_COV) | (np.max(np.abs(means), axis=1) > MAX_MEAN)
    asym = np.max(np.abs(covs - np.swapaxes(covs, 1, 2)), axis=(1, 2)) > 1e-6 * scale
    sym = 0.5 * (covs + np.swapaxes(covs, 1, 2))
    notpsd = np.zeros(n, dtype=bool)
    unsure = ~_cholesky_ok(sym) & ~huge  # Cholesky's pivots all positive: no eigenvalue below the bound
    if unsure.any():
        try:
            notpsd[unsure] = np.linalg.eigvalsh(sym[unsure])[:, 0] < -1e-9 * scale[unsure]
        except np.linalg.LinAlgError:  # no convergence: not a usable covariance either
            notpsd[unsure] = True
    for mask in (huge, asym, notpsd):
        if mask.any():
            first = min(first, int(np.argmax(mask)))
    if first < n:
        if huge[first]:
            return first, DIVERGED
        return first, ("covariance is not symmetric" if asym[first]
                       else "covariance is not positive semi-definite")
    return n, None


def _cholesky_ok(P: np.ndarray) -> np.ndarray:
    """(T,) bool: the 3x3 Cholesky factorisation of each P (T, 3, 3) runs with positive
    pivots in floating point. Then P is within a backward error of (n + 1) eps |P| (n = 3,
    about 1e-15 relative) of a positive definite matrix, so its smallest eigenvalue is above
    -1e-15 of its scale, far from the -1e-9 at which :func:`_check` calls it not positive
    semi-definite: eigvalsh would give the same verdict. False (NaN included): ask eigvalsh."""
    with np.errstate(all="ignore"):
        a00, a10, a20 = P[:, 0, 0], P[:, 1, 0], P[:, 2, 0]
        a11, a21, a22 = P[:, 1, 1], P[:, 2, 1], P[:, 2, 2]
        ok = a00 > 0.0
        l00 = np.sqrt(np.where(ok, a00, 1.0))
        l10 = a10 / l00
        l20 = a20 / l00
        p1 = a11 - l10 * l10
        ok &= p1 > 0.0
        l11 = np.sqrt(np.where(ok, p1, 1.0))
        l21 = (a21 - l20 * l10) / l11
        ok &= a22 - l20 * l20 - l21 * l21 > 0.0
    return ok


def finish_filter(m: np.ndarray, c: np.ndarray, truth: np.ndarray, done: int, failed: str | None,
                  nis_sum: float, nis_dof: int, step_ns: int, keep_means: bool) -> FilterRun:
    """One filter's record of one run from its estimates ``m`` (T, 3) and ``c`` (T, 3, 3)
    (modified: rows from the first unusable one on become NaN) and ``truth`` (T + 1, 3)."""
    T = m.shape[0]
    first, why = _check(m, c)
    if why and not failed:
        failed = why
    n_ok = min(first, done)
    m[n_ok:] = np.nan
    c[n_ok:] = np.nan
    err = pose_errors(m, truth[1:])
    nees = np.full(T, np.nan)
    if n_ok:
        with np.errstate(all="ignore"):
            nees[:n_ok] = nees_of(err[:n_ok], c[:n_ok])
        unbounded = ~np.isfinite(nees[:n_ok])
        if unbounded.any():  # a covariance that rules out its own error: the run fails there,
            n_ok = int(np.argmax(unbounded))  # before any other failure (which came later)
            failed = NEES_NOT_FINITE
            m[n_ok:], c[n_ok:], err[n_ok:], nees[n_ok:] = np.nan, np.nan, np.nan, np.nan
    var = np.einsum("tii->ti", c).copy()
    return FilterRun(err, var, nees, nis_sum, nis_dof, step_ns, done, failed,
                     m.copy() if keep_means else None)


def start_run(scenario: Scenario, seed: int, duration: float
              ) -> tuple[Simulation, int, np.ndarray, np.ndarray, np.ndarray]:
    """A run's simulation at tick 0 and its arrays to fill: the ticks T, the truth (T + 1, 3)
    with row 0 the start, the commands (T, 2) [m/s, rad/s] and the kidnap flags (T,)."""
    sim = Simulation(scenario, seed)
    T = round(duration / scenario.dt)
    truth = np.empty((T + 1, 3))
    truth[0] = sim.pose
    return sim, T, truth, np.empty((T, 2)), np.zeros(T, dtype=bool)


def one_run(scenario: Scenario, specs: list[str], params: dict[str, dict[str, Any]],
            seed: int, duration: float, index: int = 0, keep_means: bool = False,
            run_limit_s: float | None = None, secret: bytes | None = None) -> RunOutput:
    """Simulate one run and feed every filter the same steps.

    Each filter's cost counts ``predict + update + estimate``; the prior estimate read for
    the NIS between predict and update is not counted. ``run_limit_s`` [s]: a filter whose
    steps take longer than this in all is stopped ("time limit"; an endless loop), see
    ``hosting.runner.time_limit``. ``secret``: the key of the filters' random streams
    (None: the public key; a grade's secret gives its figures,
    :func:`~beacon_sim.core.streams.filter_stream`).
    """
    names = filter_names(specs)
    built: dict[str, Any] = {}
    failed: dict[str, str | None] = dict.fromkeys(names)
    for name, spec in zip(names, specs, strict=True):
        try:
            built[name] = build_filter(spec, scenario, seed, name=name,
                                       params=params.get(filter_display_name(spec)), secret=secret)
        except FilterError:
            raise  # a name or parameter that cannot work: one line, exit 2
        except BaseException as exc:  # a student's __init__ or reset: that filter fails
            if not is_filter_failure(exc):
                raise
            failed[name] = f"construction failed: {_failure_text(exc)}"
    sensors = {s.name: s for s in scenario.model_sensors}
    world = scenario.world
    sim, T, truth, controls, kidnapped = start_run(scenario, seed, duration)
    means = {n: np.full((T, 3), np.nan) for n in names}
    covs = {n: np.full((T, 3, 3), np.nan) for n in names}
    records: list = []  # measurements of the ticks that had any
    priors = {n: (np.full((T, 3), np.nan), np.full((T, 3, 3), np.nan)) for n in names}
    ns = dict.fromkeys(names, 0)
    cpu = dict.fromkeys(names, 0)  # CPU time of each filter's steps [ns]: the run limit's budget
    done = dict.fromkeys(names, 0)
    cpu_clock = time.thread_time_ns
    over = None if run_limit_s is None else f"time limit: over {run_limit_s:g} s of filter time in the run"
    for i in range(T):
        step = sim.step()
        truth[i + 1] = step.true_pose
        controls[i] = (step.control.v, step.control.omega)
        kidnapped[i] = step.kidnapped
        j = len(records)
        if step.measurements:
            records.append(step.measurements)
        for name, f in built.items():
            if failed[name]:
                continue
            left = None if run_limit_s is None else run_limit_s - cpu[name] / 1e9
            c0 = cpu_clock()
            got, why, _ = call_guarded(lambda: _timed_step(f, step), left, cpu=True,  # noqa: B023
                                       over=over)
            cpu[name] += cpu_clock() - c0
            if why is not None:  # a user's filter: switch it off, go on with the others
                failed[name] = why
                continue
            wall, prior, est = got  # type: ignore[misc]
            why = _store(est, means[name], covs[name], i)
            if why is None and prior is not None:
                why = _store(prior, priors[name][0], priors[name][1], j)
                why = None if why is None else "after predict: " + why
            if why is not None:  # a wrong shape or type: the guard's plain message
                failed[name] = why
                continue
            ns[name] += wall
            done[name] += 1
    out = RunOutput(index, seed, truth, controls, kidnapped, sim.truth_checksum)
    n_rec = len(records)
    for name in names:
        pm, pc = priors[name]
        good = np.all(np.isfinite(pm[:n_rec]), axis=1) & np.all(np.isfinite(pc[:n_rec]), axis=(1, 2))
        n_good = int(np.argmin(good)) if not good.all() else n_rec
        with np.errstate(all="ignore"):
            nis_sum, nis_dof = nis_batch(records[:n_good], pm[:n_good], pc[:n_good], sensors, world)
        out.filters[name] = finish_filter(means[name], covs[name], truth, done[name], failed[name],
                                          nis_sum, nis_dof, ns[name], keep_means)
    return out


@dataclass
class SimulatedRun:
    """One (scenario, seed) simulated once by the grader, to be streamed to every
    student's child: the truth (kept in the grader) and, per tick, the request that carries
    what a filter may see (control, dt, readings), pickled once."""

    scenario: Scenario
    index: int
    seed: int
    truth: np.ndarray  # (T + 1, 3)
    controls: np.ndarray  # (T, 2)
    kidnapped: np.ndarray  # (T,)
    truth_checksum: str
    records: list  # the readings of the ticks that had any (for the NIS)
    record_index: np.ndarray  # (T,) int: the index in ``records`` of tick i's readings
    frames: list[bytes]  # (T,) "step" requests
    #: The same run (truth, controls, events) with its readings drawn again from another
    #: stream (the probes' extra run only: does the filter use its readings?).
    frames_other: list[bytes] | None = None
    label: str = ""  # the scenario as the user named it (a shipped name or a path)
    #: The key of the run's filter streams (core/streams.py ``run_key``: a hash of the
    #: grade's secret and the seed; None: the public key's). Stays in the grader.
    key: bytes | None = None
    #: The probes' extra run (a scenario's first run only): one more seed drawn from the
    #: key, its first ticks, with its readings drawn again (hosting/feed.py ``probe_slots``).
    extra: SimulatedRun | None = None

    @property
    def stream_key(self) -> bytes:
        """The run's key (:func:`~beacon_sim.core.streams.run_key`), the public one by default."""
        from beacon_sim.core.streams import run_key

        return self.key if self.key is not None else run_key(self.seed)

    def global_seed(self, name: str) -> int:
        """The seed of the global generators of the filter ``name`` in this run, as sent to
        its child: derived from the run's key, never the seed."""
        from beacon_sim.core.streams import keyed_global_seed

        return keyed_global_seed(self.stream_key, name)

    def readings_within(self, ticks: int) -> bool:
        """Whether the first ``ticks`` ticks hold any reading."""
        n = min(ticks, len(self.frames))
        return n > 0 and any(len(r) for r in self.records[:int(self.record_index[n - 1]) + 1])


def simulate_run(scenario: Scenario, seed: int, duration: float, index: int = 0,
                 probe: bool = False, label: str | None = None,
                 secret: bytes | None = None, redraw: bool = False) -> SimulatedRun:
    """Simulate one run as :func:`one_run` does, without filters. ``probe``: also the
    probes' extra run (``extra``: one more seed drawn from the run's key, for the probes'
    ticks, its readings drawn again too); ``redraw``: this run with its readings drawn
    again (``frames_other``, from a seed derived from the run's key); ``secret``: the key
    of the filters' streams (None: the public key)."""
    from beacon_sim.core.streams import run_key
    from beacon_sim.hosting.client import step_request
    from beacon_sim.hosting.feed import PROBE_TICKS, other_readings_seed, probe_seed

    key = run_key(seed, secret)
    sim, T, truth, controls, kidnapped = start_run(scenario, seed, duration)
    other = Simulation(scenario, seed, readings_seed=other_readings_seed(key)) if redraw else None
    records: list = []
    rec = np.zeros(T, dtype=int)
    frames, other_frames = [], []
    for i in range(T):
        step = sim.step()
        truth[i + 1] = step.true_pose
        controls[i] = (step.control.v, step.control.omega)
        kidnapped[i] = step.kidnapped
        rec[i] = len(records)
        if step.measurements:
            records.append(step.measurements)
        frames.append(step_request(step.control, step.dt, step.measurements, bool(step.measurements)))
        if other is not None:
            st = other.step()
            other_frames.append(step_request(st.control, st.dt, st.measurements, bool(st.measurements)))
    if other is not None and other.truth_checksum != sim.truth_checksum:
        other_frames = []  # readings that moved the truth: no such probe here
    extra = None
    if probe:
        extra = simulate_run(scenario, probe_seed(key), min(duration, PROBE_TICKS * scenario.dt), index,
                             label=label, secret=secret, redraw=True)
    return SimulatedRun(scenario, index, seed, truth, controls, kidnapped, sim.truth_checksum,
                        records, rec, frames, other_frames or None,
                        scenario.name if label is None else label, key, extra)


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
                  probe_ticks: int | None = None) -> tuple[list[RunOutput], dict[str, Any]]:
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
    the first name."""
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
    fed = feed_batch(child, slots, run_limit_s, sims[0].global_seed(names[0]), order)
    report = dict(fed.report)
    theta = np.concatenate([fed.means(k)[:fed.done(k), 2] for k in range(R)])
    report["heading_unwrapped"] = bool(np.any(~((theta >= -np.pi) & (theta < np.pi))))
    if probes:
        ex = sims[0].extra
        within = ex is not None and ex.readings_within(min(probe_ticks or 0, len(ex.frames)))
        report["probes"] = judge_probes(fed, 0, probes, within)
    return [_run_of(fed, k, sr, name, sr.index == 0) for k, sr in enumerate(sims)], report


def _store(est: object, means: np.ndarray, covs: np.ndarray, i: int) -> str | None:
    """Write ``est`` (a ``(mean (3,), cov (3, 3))`` pair) into row ``i`` of ``means`` and
    ``covs``; its values are judged later (:func:`finish_filter`). Anything else: the
    guard's one plain line (a wrong shape says so, not numpy's "could not broadcast")."""
    got = estimate_arrays(est)
    if isinstance(got, str):
        return got
    means[i], covs[i] = got
    return None


def _timed_step(f: Any, step: Any) -> tuple[int, Any, Any]:
    """One step of one filter: (wall time of predict + update + estimate [ns], the estimate
    after predict when the tick has readings (for the NIS, not timed) or None, the
    estimate)."""
    clock = time.perf_counter_ns
    t0 = clock()
    f.predict(step.control, step.dt)
    t1 = clock()
    prior = f.estimate() if step.measurements else None
    t2 = clock()
    f.update(step.measurements)
    est = f.estimate()
    t3 = clock()
    return (t1 - t0) + (t3 - t2), prior, est


def _failure_text(exc: BaseException) -> str:
    """One line for what a filter's code raised (SystemExit and KeyboardInterrupt included)."""
    return failure_line(exc)


def _task(args) -> RunOutput:
    return one_run(*args)


def _task_group(group: list[Any]) -> list[RunOutput]:
    """Several runs in one Dask task, in order (each as :func:`_task`: the same results)."""
    return [one_run(*args) for args in group]


#: How many tasks each Dask worker gets on the per-run path: runs are grouped into about
#: this many tasks a worker (fewer tasks, less scheduling and serialisation; enough of them
#: that one slow group does not leave the other workers idle long).
TASKS_PER_DASK_WORKER = 3

#: Dask settings for the workers (and the client) of ``eval --scheduler`` and grading
#: (issue 27; docs/performance.md): with no task to run, a Dask cluster still spends CPU on
#: its event loops' ticks, its memory and system monitors and the workers' sampling
#: profiler, in proportion to the wall time: 115 ms of CPU a second for a LocalCluster of
#: 2 workers with Dask's defaults, 16 ms with these, so eval on Dask costs within a few per
#: cent of local processes. None of them changes a result. Apply with
#: ``dask.config.set(DASK_LEAN_CONFIG)`` before a LocalCluster is made, or as a worker's
#: YAML / ``DASK_...`` environment (docs/performance.md).
DASK_LEAN_CONFIG: dict[str, Any] = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "500ms",
    "distributed.admin.system-monitor.interval": "2s",
    "distributed.worker.memory.monitor-interval": "1s",
}


def default_jobs() -> int:
    """All the cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:
        return max(1, os.cpu_count() or 1)


def batch_reason(scenario: Scenario, specs: list[str], params: dict[str, dict[str, Any]]) -> str | None:
    """Why the runs cannot be batched (None: every filter has a batched form that
    reproduces it, as the filter itself says: ``batch_blocker``)."""
    for spec in specs:
        try:
            cls = load_filter_class(spec)
        except Exception as exc:  # reported by the per-run path
            return str(exc)
        if not issubclass(cls, BatchableFilter):
            return f"{spec} has no batched form"
        try:
            flt = build_filter(spec, scenario, 0, params=params.get(filter_display_name(spec)))
        except Exception as exc:
            return str(exc)
        if not isinstance(flt, Batchable):  # the batched contract (filters/base.py)
            return f"{spec} has no batched form"
        why = flt.batch_blocker
        if why is not None:
            return f"{spec}: {why}"
    return None


def _batchable(flt: object) -> Batchable:
    """``flt`` as a filter with a batched form (batch_reason has checked it)."""
    if not isinstance(flt, Batchable):
        raise FilterError(f"{type(flt).__name__} has no batched form")
    return flt


def batch_runs(scenario: Scenario, specs: list[str], params: dict[str, dict[str, Any]],
               seeds: list[int], duration: float, indices: list[int],
               keep_means_index: int = 0) -> list[RunOutput]:
    """Runs ``seeds`` together, every filter batched (see :func:`batch_reason`); returns one
    :class:`RunOutput` per seed, as :func:`one_run` would. Costs: the batch's per run-step;
    the NIS against the predicted belief is not timed (as in one_run), except for a filter
    whose update gives it (``own_nis``)."""
    names = filter_names(specs)
    R = len(seeds)
    batched = {name: _batchable(build_filter(spec, scenario, seeds[0], name=name,
                                             params=params.get(filter_display_name(spec)))).batched(R)
               for name, spec in zip(names, specs, strict=True)}
    batch = BatchSimulation(scenario, seeds, readings_checksums=False)   # R single runs, bit for bit
    packer = SlotPacker(scenario.world, scenario.model_sensors)
    T = round(duration / scenario.dt)
    truth = np.empty((R, T + 1, 3))
    truth[:, 0] = batch.pose
    controls = np.empty((R, T, 2))
    kidnapped = np.zeros((R, T), dtype=bool)
    means = {n: np.empty((R, T, 3)) for n in names}
    covs = {n: np.empty((R, T, 3, 3)) for n in names}
    nis_sum = {n: np.zeros(R) for n in names}
    nis_dof = {n: np.zeros(R, dtype=int) for n in names}
    nis_alive = {n: np.ones(R, dtype=bool) for n in names}
    ns = dict.fromkeys(names, 0)
    clock = time.perf_counter_ns
    with np.errstate(all="ignore"):
        for t in range(T):
            tick = batch.advance()   # the tick as arrays: no Step or Measurement per run
            v = tick.v
            w = tick.omega
            controls[:, t, 0] = v
            controls[:, t, 1] = w
            truth[:, t + 1] = tick.pose
            kidnapped[:, t] = tick.kidnapped
            dt = tick.dt
            st = packer.pack_tick(tick)
            if st is not None:
                valid = st.valid if st.valid is not None else np.ones(st.z.shape, dtype=bool)
                dof = np.count_nonzero(valid, axis=1)
                has = dof > 0   # the run had a reading: its NIS is recorded
            for name, f in batched.items():
                t0 = clock()
                f.predict(v, w, dt)
                t1 = clock()
                prior = None
                if st is not None and not f.own_nis:  # not timed (as one_run)
                    prior = nis(f.mean, f.cov, st)
                t2 = clock()
                if st is not None:
                    f.update(st)
                    if prior is None:
                        prior = f.last_nis
                means[name][:, t] = f.mean
                covs[name][:, t] = f.cov
                t3 = clock()
                ns[name] += (t1 - t0) + (t3 - t2)
                if st is not None and prior is not None:
                    alive = nis_alive[name]
                    alive &= np.isfinite(prior) | ~has
                    use = alive & has
                    nis_sum[name][use] += prior[use]
                    nis_dof[name][use] += dof[use]
    checksums = batch.truth_checksums()
    out = []
    for i in range(R):
        run = RunOutput(indices[i], seeds[i], truth[i], controls[i], kidnapped[i], checksums[i])
        for name in names:
            run.filters[name] = finish_filter(
                means[name][i].copy(), covs[name][i].copy(), truth[i], T, None,
                float(nis_sum[name][i]), int(nis_dof[name][i]), round(ns[name] / R),
                keep_means=indices[i] == keep_means_index)
        out.append(run)
    return out


def _batch_task(args) -> list[RunOutput]:
    return batch_runs(*args)


def run_monte_carlo(scenario: Scenario, specs: list[str], runs: int, seed: int = 0,
                    duration: float | None = None, jobs: int | None = None,
                    params: dict[str, dict[str, Any]] | None = None,
                    progress: bool | None = None,
                    on_run: Callable[[RunOutput], None] | None = None,
                    batch: bool | None = None,
                    run_limit_s: float | None = None,
                    scheduler: Any = None) -> list[RunOutput]:
    """``runs`` runs with seeds ``seed, seed + 1, ...``; returns them in seed order.

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
        chunks = [list(range(a, b)) for a, b in pairwise(bounds) if b > a]
        btasks = [(scenario, list(specs), params, [seed + i for i in c], duration, c, 0) for c in chunks]

        def collect(done: list[RunOutput]) -> None:
            for r in done:
                out[r.index] = r
                bar.advance()
                if on_run:
                    on_run(r)

        if scheduler is not None:
            on_dask(scheduler, _batch_task, btasks, lambda _i, done: collect(done))
        elif len(btasks) == 1:
            collect(_batch_task(btasks[0]))
        else:
            with ProcessPoolExecutor(max_workers=len(btasks), initializer=init_worker) as pool:
                for fut in as_completed([pool.submit(_batch_task, t) for t in btasks]):
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
                out[i] = r
                bar.advance()
                if on_run:
                    on_run(r)

        on_dask(scheduler, _task_group, [[tasks[i] for i in g] for g in groups], group_done)
    elif jobs == 1:
        for i, t in enumerate(tasks):
            run = _task(t)
            out[i] = run
            bar.advance()
            if on_run:
                on_run(run)
    else:
        with ProcessPoolExecutor(max_workers=jobs, initializer=init_worker) as pool:
            futures = {pool.submit(_task, t): i for i, t in enumerate(tasks)}
            for done in as_completed(futures):
                run = done.result()
                out[futures[done]] = run
                bar.advance()
                if on_run:
                    on_run(run)
    return [o for o in out if o is not None]


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


class ClusterError(RuntimeError):
    """The Dask cluster lost a task (its worker died, the scheduler went away)."""


#: The exceptions of ``dask.distributed`` that mean a task was lost, not that it raised.
_LOST = ("KilledWorker", "CommClosedError", "CancelledError", "FutureCancelledError")


def dask_client(scheduler: Any) -> tuple[Any, bool]:
    """A ``dask.distributed`` Client for ``scheduler`` (a Client: itself; a cluster or an
    address: a new one) and whether it is ours to close."""
    from dask.distributed import Client

    if isinstance(scheduler, Client):
        return scheduler, False
    return Client(scheduler, timeout="20s", set_as_default=False), True


def dask_workers(scheduler: Any) -> int:
    """How many workers the Dask cluster has now."""
    client, own = dask_client(scheduler)
    try:
        return len(client.scheduler_info().get("workers", {}))
    finally:
        if own:
            client.close()


def on_dask(scheduler: Any, fn: Callable[..., Any], tasks: list[Any],
            done: Callable[[int, Any], None],
            lost: Callable[[int, Exception], None] | None = None, shared: Any = None) -> None:
    """``fn(task)`` for every task on Dask, ``done(index, result)`` as each finishes; each
    result is released once gathered (the scheduler forgets it: never computed again).
    ``shared``: data every task needs (grading's simulated runs), sent to every worker once
    (scattered) instead of once per task, and given as ``fn(task, shared)``.

    A task that raised or whose worker died: ``lost(index, exc)`` when given (grading:
    that task's student fails, the others go on), else a one-line :class:`ClusterError`
    for a lost worker and the exception itself otherwise."""
    from dask.distributed import as_completed

    client, own = dask_client(scheduler)
    data = None
    try:
        if shared is not None:
            (data,) = client.scatter([shared], broadcast=True, hash=False)
            futures = client.map(fn, list(tasks), shared=data, pure=False)
        else:
            futures = client.map(fn, list(tasks), pure=False)
        index = {f.key: i for i, f in enumerate(futures)}
        for fut in as_completed(futures, loop=client.loop):  # not the default client's loop
            i = index[fut.key]
            try:
                result = fut.result()
            except Exception as exc:  # the worker died or the cluster went away: one line
                fut.release()
                if lost is not None:
                    lost(i, exc)
                    continue
                if type(exc).__name__ in _LOST:
                    raise ClusterError(f"Dask: task {i + 1} of {len(futures)} was lost "
                                       f"({type(exc).__name__}: {str(exc)[:200]})") from None
                raise
            fut.release()
            done(i, result)
    finally:
        if data is not None:
            data.release()
        if own:
            client.close()


def limit_worker_memory(gb: float) -> None:
    """A local worker's address-space limit, so a filter that hoards memory gets a
    MemoryError (a failed run) instead of the kernel's out-of-memory killer."""
    if gb <= 0:
        return
    try:
        import resource

        limit = int(gb * 2**30)
        _soft, hard = resource.getrlimit(resource.RLIMIT_AS)
        if hard != resource.RLIM_INFINITY:
            limit = min(limit, hard)
        resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
    except (ImportError, ValueError, OSError):
        pass


#: A local evaluation worker's address-space limit [GB]: a filter that hoards memory fails
#: its run with a MemoryError instead of the kernel killing the worker (and the sweep).
WORKER_MEMORY_GB = 4.0


def init_worker(memory_gb: float = WORKER_MEMORY_GB) -> None:
    """Set up a local worker process: one BLAS thread, and the memory limit."""
    limit_blas_threads()
    limit_worker_memory(memory_gb)


def stack(runs: list[RunOutput], name: str, attr: str) -> np.ndarray:
    """One filter's per-step array from every run, stacked: (R, T, ...)."""
    return np.stack([getattr(r.filters[name], attr) for r in runs])


__all__ = ["DASK_LEAN_CONFIG", "TASKS_PER_DASK_WORKER", "ClusterError", "FilterRun", "RunOutput",
           "SimulatedRun", "batch_reason", "batch_runs", "dask_client", "dask_workers", "filter_names",
           "finish_filter", "hosted_runs",
           "isolated_run", "isolated_runs", "on_dask", "one_run", "run_monte_carlo",
           "run_monte_carlo_isolated", "simulate_run", "stack"]


@dataclass
class TeamRunOutput:
    """One run over N robots: the truth (T + 1, N, 3) with row 0 the start, the commands
    (T, N, 2), kidnaps (T, N), and per filter one :class:`FilterRun` per robot (team order)."""

    index: int
    seed: int
    truth: np.ndarray
    controls: np.ndarray
    kidnapped: np.ndarray
    truth_checksum: str
    filters: dict[str, list[FilterRun]] = field(default_factory=dict)

    def robot(self, i: int) -> RunOutput:
        """Robot i's view as a single-robot run (what ``summary.evaluate`` reads)."""
        out = RunOutput(self.index, self.seed, self.truth[:, i], self.controls[:, i],
                        self.kidnapped[:, i], self.truth_checksum)
        out.filters = {name: runs[i] for name, runs in self.filters.items()}
        return out


def team_one_run(team: TeamScenario, specs: list[str], params: dict[str, dict[str, Any]] | None,
                 seed: int, duration: float, index: int = 0,
                 step_limit_s: float | None = HEADLESS_STEP_LIMIT_S,
                 run_limit_s: float | None = None, secret: bytes | None = None) -> TeamRunOutput:
    """One guarded headless run over N robots reduced to arrays; the limits and ``secret``
    as :func:`~beacon_sim.runs.headless.run_headless`'s. A filter's time is its time per
    tick over every robot."""
    res = run_headless(team, specs, seed=seed, duration=duration, params=params,
                       step_limit_s=step_limit_s, run_limit_s=run_limit_s, secret=secret)
    T, N = len(res.team_steps), team.n_robots
    truth = np.empty((T + 1, N, 3))
    truth[0] = res.initial_poses
    truth[1:] = res.true_poses
    kidnapped = np.array([[st.kidnapped for st in s.steps] for s in res.team_steps],
                         dtype=bool).reshape(T, N)
    out = TeamRunOutput(index, seed, truth, res.controls, kidnapped, res.truth_checksum)
    for name in res.names:
        _, got_means, got_covs = res.filters.series(name)
        done = len(got_means)
        means = np.full((T, N, 3), np.nan)
        covs = np.full((T, N, 3, 3), np.nan)
        means[:done], covs[:done] = got_means, got_covs
        step_ns = (sum(m.tracks[name].step_ns for m in res.filters.members) if res.filters.is_member(name)
                   else res.filters.joint.tracks[name].step_ns)
        failed = res.track(name).failed
        out.filters[name] = [finish_filter(means[:, i].copy(), covs[:, i].copy(), truth[:, i], done,
                                           failed, 0.0, 0, step_ns, keep_means=index == 0)
                             for i in range(N)]
    return out


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
