"""Conformance checks for any filter (docs/architecture.md), used by ``beacon-sim check``.

``check`` feeds a filter as ``grade`` does (watched and scored look the same):
the same batch protocol (:mod:`beacon_sim.hosting.feed`: one run of a default grade's length
on a fresh random seed, and the grade's probes, in an order drawn from a fresh random key),
the same limits (a default grade's: its run's CPU-time budget, its child's memory and CPU
backstop), the same random streams (keyed by a fresh secret, never the seed) and the same
verdicts (the guard's rules and words, :mod:`beacon_sim.hosting.guard`). A file is hosted in
a child process of its own, started as a grade starts it; a built-in filter (or
``--sandbox none``) is served in this process by the same code
(:class:`~beacon_sim.hosting.feed.LocalChild`).

From what the filter returned the checks judge, each on its own (one fault, one FAIL): the
interface, the construction, that every step returned, shapes, finite values (not diverged,
and a covariance that leaves room for the error it had: a finite NEES), a symmetric positive
semi-definite covariance, a heading in [-pi, pi), ``belief()``, that an update without
readings is accepted, that the run fed again gives bit-identical estimates, and that the
filter draws nothing from the global ``np.random`` / ``random`` generators; the report ends
with the cost per step beside a built-in filter's of its own kind (ekf, ekf_slam or mcl).

This module runs the filter (where it is hosted, the simulated runs, the batch fed as a
grade feeds it) and puts the checks together in order; each check's verdict is
:mod:`beacon_sim.hosting.check_verdicts`, what a check says and the printed report
:mod:`beacon_sim.hosting.check_report` (their names the CLI and tests use are re-exported
here).

Scenario: when the given scenario has no sensor the filter can use (a filter may say which
kinds it uses in a ``sensor_kinds`` class attribute, e.g. the KF uses pose and position
fixes), the first shipped scenario with such a sensor is used instead, and the report says
so.
"""

from __future__ import annotations

import pickle
import secrets
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from beacon_sim.core.scenario import Scenario, load_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.core.streams import keyed_global_seed, keyed_stream, run_key
from beacon_sim.filters.base import FilterContext, FilterError
from beacon_sim.hosting.check_report import NO_STEP, CheckResult, print_report, verdict
from beacon_sim.hosting.check_verdicts import (
    LANDMARKS_ADVICE,
    RUNS_ADVICE,
    EmptyTrial,
    FedSteps,
    RngTrial,
    check_belief,
    check_constructs,
    check_covariance_psd,
    check_covariance_symmetric,
    check_determinism,
    check_empty_update,
    check_finite,
    check_global_rng,
    check_heading_wrapped,
    check_landmarks,
    check_shapes,
    cost_peer,
    estimate_problems,
    loads_failed,
)
from beacon_sim.hosting.client import FilterChild, start_child, step_request
from beacon_sim.hosting.containment import resolve_sandbox
from beacon_sim.hosting.feed import (
    GRADE_RUN_S,
    GRADE_SEEDS,
    GRADE_TIME_LIMIT_S,
    PROBE_TICKS,
    Fed,
    LocalChild,
    Slot,
    feed_batch,
    grade_limits,
    judge_probes,
    other_readings_seed,
    probe_seed,
    probe_slots,
    reply_timeout,
    slot_order,
    step_frames,
)
from beacon_sim.hosting.landmark_check import landmark_map_problems
from beacon_sim.hosting.loading import (
    FilterLoadError,
    filter_display_name,
    initial_belief,
    load_filter_class,
    merged_params,
)
from beacon_sim.hosting.sources import hosted_source
from beacon_sim.hosting.watchdog import FilterFailed

#: How long check's run is [s] (a default grade's run; at most the scenario's length) and its
#: CPU-time budget [s] (a default grade's time limit): over it, "runs" fails ("time limit").
RUN_S = GRADE_RUN_S
RUN_LIMIT_S = GRADE_TIME_LIMIT_S


def _scenario_for(host: Any, scenario: Scenario) -> tuple[Scenario, str]:
    kinds = host.info.get("sensor_kinds")
    if not kinds or any(s.kind in kinds for s in scenario.sensors):
        return scenario, ""
    from beacon_sim.core.resources import shipped_scenarios

    for name in shipped_scenarios():
        other = load_scenario(name)
        if any(s.kind in kinds for s in other.sensors):
            return other, (f"scenario {scenario.name} has no {'/'.join(kinds)} sensor; "
                           f"checked on {other.name} instead")
    return scenario, f"no shipped scenario has a {'/'.join(kinds)} sensor"


class _Host:
    """Where the checked filter runs: ``child``, a :class:`FilterChild` (a file or a module
    filter, hosted as ``grade`` hosts one) or a :class:`LocalChild` (in this process)."""

    def __init__(self, child: FilterChild, hosted: bool, log: Path | None = None):
        self.child = child
        self.hosted = hosted
        self.log = log  # the child's stdout and stderr
        self.info = child.info
        self.where = (f"{self.info.get('module', '?')}.{child.class_name}"
                      + (" (in a process of its own)" if hosted else ""))
        self.missing = list(self.info.get("missing") or [])

    def context(self, scenario: Scenario, spec: str, key: bytes) -> FilterContext:
        """The filter's context: named and parametrised as ``grade`` names a hosted filter
        (its class) or as ``run`` names a built-in one, its generator keyed by ``key``."""
        if self.hosted:
            name = self.child.class_name
            params = dict(scenario.filter_params.get(name, {}))
        else:
            name = filter_display_name(spec)
            params = merged_params(spec, scenario)
        return FilterContext.of_scenario(scenario, name, params, keyed_stream(key, name))

    def close(self) -> None:
        self.child.close()


def _open_host(spec: str, isolated: bool, sandbox: str) -> _Host:
    """Where the checked filter runs: a file or module filter in a child process
    (``isolated``) started with a default grade's limits, else here. Raises FilterError (the
    name is no filter: one line, exit status 2) or FilterFailed (the file does not import)."""
    where = hosted_source(spec) if isolated else None
    if where is not None:
        path, cls = where
        if isinstance(path, Path) and not path.is_file():
            raise FilterLoadError(f"{path}: no such filter file")
        log = Path(tempfile.mkdtemp(prefix="beacon-sim-check-")) / "log.txt"
        child = start_child(path, cls, log, resolve_sandbox(sandbox), grade_limits(),
                            reply_timeout_s=reply_timeout(RUN_LIMIT_S))
        return _Host(child, True, log)
    return _Host(LocalChild(load_filter_class(spec)), False)


@dataclass
class _Run:
    """A run check feeds: its key and seed, its steps' truth (T + 1, 3), the "step"
    requests, whether each tick has readings; the probes' extra run (the first run only:
    one more seed drawn from the key) and, for that extra run, its frames with the
    readings drawn again."""

    seed: int
    key: bytes
    truth: np.ndarray
    frames: list[bytes]
    has_readings: list[bool]
    extra: _Run | None = None
    redrawn: list[bytes] | None = None


def _simulate(scenario: Scenario, seed: int, secret: bytes, ticks: int, probe: bool,
              redraw: bool = False) -> _Run:
    """Run ``seed`` of ``scenario`` for ``ticks`` ticks, its filter streams keyed by
    ``secret`` (as ``grade``'s simulate_run); ``probe``: also the probes' extra run;
    ``redraw``: also this run with its readings drawn again."""
    key = run_key(seed, secret)
    steps = Simulation(scenario, seed).run(ticks * scenario.dt)
    truth = np.array([scenario.initial_pose] + [st.true_pose for st in steps], dtype=float)
    run = _Run(seed, key, truth, step_frames(steps), [bool(st.measurements) for st in steps])
    if redraw:
        again = Simulation(scenario, seed, readings_seed=other_readings_seed(key)).run(ticks * scenario.dt)
        run.redrawn = step_frames(again)
    if probe:
        run.extra = _simulate(scenario, probe_seed(key), secret, min(ticks, PROBE_TICKS), False, True)
    return run


def check_loads(host: _Host) -> CheckResult:
    """Does the filter load? (It did, when there is a host: say where it came from.)"""
    return verdict("loads", True, host.where)


def check_scenario(host: _Host, scenario: Scenario) -> tuple[Scenario, list[CheckResult]]:
    """Which scenario the filter is checked on, and a note when it is not the given one."""
    used, note = _scenario_for(host, scenario)
    return used, ([verdict("scenario", True, note)] if note else [])


def check_interface(host: _Host) -> CheckResult:
    """Does the class have the five methods of ``beacon_sim.filters.base.Filter``?"""
    missing = host.missing
    return verdict("interface", not missing,
                   f"missing: {', '.join(missing)}" if missing
                   else "reset, predict, update, estimate, belief",
                   "implement every method of beacon_sim.filters.base.Filter (subclass "
                   "FilterBase to get belief() for free)")


def _slam_scenario(scenario: Scenario) -> tuple[Scenario, str]:
    """The scenario the map check runs on: ``scenario`` when its map is withheld, else
    ``slam_loop`` (on a known map a SLAM filter has no landmarks to report)."""
    if not scenario.map_known:
        return scenario, ""
    return load_scenario("slam_loop"), " (on slam_loop: the given scenario's map is known)"


def report_cost(run: FedSteps, scenario: Scenario, frames: Sequence[bytes],
                mapping: bool = False) -> CheckResult:
    """The cost per step [us] over ``run``'s steps beside that of the built-in peer of its
    kind (:func:`cost_peer`) fed ``frames`` (the first run's steps) in this process. Not a
    check (a NOTE); nothing to report when no step ran."""
    if not run.estimates:
        return verdict("cost", True, "no step ran: no cost to report", note=True)
    mine = run.step_ns / 1e3 / len(run.estimates)
    own = f"{mine:.1f} us per step (predict + update + estimate)"
    peer = cost_peer(scenario, mapping)
    try:
        cls = load_filter_class(peer)
        n = len(frames)
        key = run_key(0)
        ctx = FilterContext.of_scenario(scenario, peer, merged_params(peer, scenario),
                                        keyed_stream(key, peer))
        ref = feed_batch(LocalChild(cls), [Slot(ctx, initial_belief(scenario), frames, n, peer)], None,
                         keyed_global_seed(key, peer))
    except Exception:  # a peer that cannot read this scenario: no ratio rather than a wrong one
        return verdict("cost", True, own, note=True)
    if ref.failed[0] is not None or not ref.done(0):
        return verdict("cost", True, own, note=True)
    peer_us = float(ref.walls[:, 0].sum()) / 1e3 / max(ref.done(0), 1)
    return verdict("cost", True, f"{own}; the built-in {peer}: {peer_us:.1f} us on the same steps "
                   f"({mine / max(peer_us, 1e-9):.1f}x)", note=True)


def report_output(host: _Host) -> list[CheckResult]:
    """Where the filter's printed output went, if it printed anything (not a check)."""
    log = host.log
    if log is not None and log.exists() and log.stat().st_size:
        return [verdict("output", True, f"the filter printed {log.stat().st_size} bytes: see {log}",
                        note=True)]
    return []


def run_checks(spec: str, scenario: Scenario, *, isolated: bool = True, sandbox: str = "auto",
               seeds: Sequence[int] | None = None) -> list[CheckResult]:
    """Run every check on the filter named ``spec`` with ``scenario``'s map and sensors.

    The filter is run as a default grade runs it (:data:`~beacon_sim.hosting.feed.GRADE_SEEDS`
    runs of :data:`RUN_S` seconds, fed together with the probes of the first): a file in a
    child process of its own (``isolated``, the default; ``sandbox`` as for ``grade``),
    started with a grade's limits; its code never runs in this process, and a filter that
    exits, loops or raises ``KeyboardInterrupt`` fails a check instead of ending the
    program. ``seeds``: the runs' seeds (default fresh random ones, as unknown to the filter
    as a grade's; the report names them).

    Each check stands on its own, so one fault gives one FAIL: a filter that raises at step
    k fails "runs" and is judged by the other checks on the steps before k; a NaN fails
    "finite" only (the determinism check counts NaN equal to NaN). The last line is the
    cost per step beside the built-in ekf's on the same steps (not a check).
    """
    try:
        host = _open_host(spec, isolated, sandbox)
    except (FilterError, FilterFailed) as exc:
        return [loads_failed(exc)]
    results: list[CheckResult] = []
    try:
        chosen = [secrets.randbelow(2**63) for _ in range(GRADE_SEEDS)] if seeds is None else list(seeds)
        results += _checks(host, spec, scenario, [int(s) for s in chosen])
    finally:
        host.close()
        results += report_output(host)
    return results


def _fed_feed(fed: Fed, k: int, ticks: int | None = None) -> FedSteps:
    """Slot k of ``fed`` as a :class:`FedSteps` (its first ``ticks`` ticks)."""
    n = fed.done(k) if ticks is None else min(fed.done(k), ticks)
    est: list[object] = [(fed.store[i, k, 12:15].copy(), fed.store[i, k, 15:24].reshape(3, 3).copy())
                         for i in range(n)]
    err = None
    if fed.failed[k] is not None and (ticks is None or int(fed.failed_at[k] or 0) < ticks):
        err = (int(fed.failed_at[k] or 0) + 1, fed.failed[k] or "")
    return FedSteps(est, err, int(fed.walls[:n, k].sum()))


def _judge_run(fed: Fed, k: int, run: _Run) -> tuple[FedSteps, dict[str, str], str]:
    """Run k of ``fed`` (simulated as ``run``) judged: its steps (with the failure that
    ended it, unless that was an estimate's form, a "shapes" problem, or its map, the
    "landmarks" check's), its value problems, and what to add to "runs"' message."""
    feed = _fed_feed(fed, k)
    first = fed.first[k]
    after_reset: list[object] = [first] if isinstance(first, tuple) else []
    problems = estimate_problems(after_reset, feed.estimates, run.truth[1:])
    failure, note = feed.error, ""
    if failure is not None and failure[1].startswith("landmarks()"):
        feed = FedSteps(feed.estimates, None, feed.step_ns)
        note = f"; stopped at step {failure[0]} by its map: see landmarks"
    elif failure is not None and failure[1].startswith(("estimate() returned", "after predict: estimate()")):
        problems.setdefault("shapes", f"step {failure[0]}: {failure[1].removeprefix('after predict: ')}")
        feed = FedSteps(feed.estimates, None, feed.step_ns)  # every step returned: its form is "shapes"
        note = f"; stopped at step {failure[0]}: see shapes"
    return feed, problems, note


def _in_run(r: int, run: _Run, text: str) -> str:
    """``text`` said of run r (the first run's words are plain; the others name their run)."""
    return text if r == 0 else f"run {r + 1} (seed {run.seed}), {text}"


def _checks(host: _Host, spec: str, scenario: Scenario, seeds: Sequence[int]) -> list[CheckResult]:
    """The checks after the filter loaded, in order (see :func:`run_checks`); the list stops
    after "interface" or "constructs" when that one fails."""
    results = [check_loads(host)]
    scenario, notes = check_scenario(host, scenario)
    results += notes
    results.append(check_interface(host))
    if not results[-1].passed:
        return results
    secret = secrets.token_bytes(32)  # as a grade's: the filter's streams keyed afresh
    ticks = round(RUN_S / scenario.dt)
    sims = [_simulate(scenario, seed, secret, ticks, probe=r == 0) for r, seed in enumerate(seeds)]
    R = len(sims)
    ctxs = [host.context(scenario, spec, run.key) for run in sims]
    name = ctxs[0].name
    slots = [Slot(ctx, initial_belief(scenario), run.frames, ticks, name)
             for ctx, run in zip(ctxs, sims, strict=True)]
    probes: dict[str, int] = {}
    ex = sims[0].extra
    assert ex is not None and ex.redrawn is not None
    extra = Slot(host.context(scenario, spec, ex.key), initial_belief(scenario), ex.frames, len(ex.frames),
                 name)
    for what, slot in probe_slots(0, slots[0], (extra, ex.redrawn), PROBE_TICKS):
        probes[what] = len(slots)
        slots.append(slot)
    fed = feed_batch(host.child, slots, RUN_LIMIT_S, keyed_global_seed(sims[0].key, name),
                     slot_order(sims[0].key, len(slots)))
    unbuilt = next((r for r in range(R) if not fed.built[r]), None)
    results.append(check_constructs(None if unbuilt is None else fed.failed[unbuilt]))
    if unbuilt is not None:
        return results
    judged = [_judge_run(fed, r, run) for r, run in enumerate(sims)]
    problems: dict[str, str] = {}
    for r, (_, found, _) in enumerate(judged):
        for key, text in found.items():
            problems.setdefault(key, _in_run(r, sims[r], text))
    failing = next((r for r in range(R) if judged[r][0].error is not None), None)
    n_meas = sum(len(m) for r, run in enumerate(sims)
                 for f in run.frames[:len(judged[r][0].estimates)] for m in pickle.loads(f[4:])[3])
    if failing is None:
        seeds_text = ", ".join(str(run.seed) for run in sims)
        runs = verdict("runs", True, f"{R} run{'s' if R > 1 else ''} of {ticks} steps, {n_meas} readings "
                       f"(seed{'s' if R > 1 else ''} {seeds_text}){''.join(j[2] for j in judged)}")
        empty = verdict("empty update", True, "accepted on the "
                        f"{sum(1 for run in sims for h in run.has_readings if not h)} ticks without readings")
    else:
        err = judged[failing][0].error
        assert err is not None
        runs = verdict("runs", False, _in_run(failing, sims[failing], f"step {err[0]}: {err[1]}"),
                       RUNS_ADVICE)
        runs, empty = _empty_update(host, fed, failing, sims[failing], runs, slots[failing])
    pf = judge_probes(fed, 0, probes, any(ex.has_readings))
    for what, (why, at) in pf.failures.items():  # the probes are runs too: failing one fails "runs"
        if runs.passed and empty.passed and what != "again":  # ("again": not deterministic)
            runs = verdict("runs", False, f"one more run (seed {ex.seed}), step {at + 1}: {why}", RUNS_ADVICE)
    values = [check_shapes(problems), check_finite(problems), check_covariance_symmetric(problems),
              check_covariance_psd(problems), check_heading_wrapped(problems)]
    stepped = any(j[0].estimates for j in judged)
    if not stepped and not problems:  # nothing to judge: say so
        values = [verdict(v.name, True, NO_STEP) for v in values]
    belief_fault = next((r for r in range(R) if fed.beliefs[r] not in (None, "not asked")), None)
    belief = check_belief(fed.beliefs[0] if belief_fault is None
                          else _in_run(belief_fault, sims[belief_fault], fed.beliefs[belief_fault] or ""))
    landmarks = _landmarks(host, fed, scenario, spec, secret, seeds)
    k_again = probes["again"]
    horizon = fed.done(k_again) + (fed.failed[k_again] is not None)
    again = _fed_feed(fed, probes["again"]) if "again" in probes else FedSteps([], None, 0)
    rng = RngTrial(_fed_feed(fed, 0, horizon), again, bool(fed.report.get("np_global")),
                    bool(fed.report.get("py_global")), None, pf)
    readings = [] if pf.readings_used is not False else [verdict(
        "readings", True, "the estimates do not change when the readings are drawn again: the "
        "filter uses none of them (grade says so too)", note=True)]
    steps = [j[0] for j in judged]
    cost = FedSteps([e for f in steps for e in f.estimates], None, sum(f.step_ns for f in steps))
    after = [belief, *landmarks, empty, check_determinism(rng), check_global_rng(rng)]
    if not stepped:  # a filter that never ran a step passes nothing it was not asked (FAILs stay)
        after = [r if not r.passed else verdict(r.name, True, NO_STEP) for r in after]
    return [*results, runs, *values, *after, *readings,
            report_cost(cost, scenario, sims[0].frames, host.info.get("landmarks") is True)]


def _empty_update(host: _Host, fed: Fed, r: int, run: _Run, runs: CheckResult,
                  main: Slot) -> tuple[CheckResult, CheckResult]:
    """The "empty update" check, and "runs" as it stands after it, for run r that failed.
    Updates without readings happen on most ticks: when the run failed at one, a fresh
    filter is fed that tick alone (its estimate after predict asked, so that the update is
    judged alone) and, apart, a tick with readings: the empty update is to blame only if the
    tick with readings works (then "runs" passes: one fault, one FAIL)."""
    k = int(fed.failed_at[r] or 0)
    if k >= len(run.frames) or run.has_readings[k]:
        n = sum(1 for h in run.has_readings[:fed.done(r)] if not h)
        return runs, verdict("empty update", True, f"accepted on the {n} ticks without readings before")
    _, control, dt, meas, _want = pickle.loads(run.frames[k][4:])
    empty = step_request(control, dt, meas, True)
    with_readings = next((f for f, h in zip(run.frames, run.has_readings, strict=True) if h), None)
    slots = [Slot(main.ctx, main.initial, [empty], 1, main.spec)]
    if with_readings is not None:
        slots.append(Slot(main.ctx, main.initial, [with_readings], 1, main.spec))
    trial = feed_batch(host.child, slots, RUN_LIMIT_S, keyed_global_seed(run.key, main.spec))
    if not trial.built[0]:
        return runs, verdict("empty update", True, "not judged: the filter failed before (see above)")
    ok_with_readings = len(slots) > 1 and trial.failed[1] is None
    if trial.failed[0] is not None:
        if ok_with_readings:
            return (CheckResult("runs", True, _in_run(r, run, f"stopped at step {k + 1}, a step without "
                                                      "readings: the empty update fault below")),
                    check_empty_update(EmptyTrial(None, None, trial.failed[0], None)))
        return runs, CheckResult("empty update", True, "not judged: update fails with readings too "
                                 "(see runs)")
    store = trial.store[0, 0]
    before = (store[0:3].copy(), store[3:12].reshape(3, 3).copy())
    after = (store[12:15].copy(), store[15:24].reshape(3, 3).copy())
    return runs, check_empty_update(EmptyTrial(before, after, None, None))


def _landmarks(host: _Host, fed: Fed, scenario: Scenario, spec: str, secret: bytes,
               seeds: Sequence[int]) -> list[CheckResult]:
    """For a SLAM filter (one with ``landmarks()``): its map, judged on every step as ``grade``
    judges it, on the scenario checked when its map is withheld (the first run's maps), else
    on ``slam_loop`` (runs of their own, as a grade's second scenario). No result for a
    filter without ``landmarks()``."""
    if host.info.get("landmarks") is not True:
        return []
    used, note = _slam_scenario(scenario)
    if not note:
        return [check_landmarks(fed, 0, "")]
    ticks = round(RUN_S / used.dt)
    sims = [_simulate(used, seed, secret, ticks, probe=False) for seed in seeds]
    ctxs = [host.context(used, spec, run.key) for run in sims]
    own = feed_batch(host.child, [Slot(ctx, initial_belief(used), run.frames, ticks, ctx.name)
                                  for ctx, run in zip(ctxs, sims, strict=True)],
                     RUN_LIMIT_S, keyed_global_seed(sims[0].key, ctxs[0].name))
    if not own.built[0]:
        return [verdict("landmarks", False, f"not built on {used.name}: {own.failed[0]}", LANDMARKS_ADVICE)]
    return [check_landmarks(own, 0, note)]


__all__ = ["CheckResult", "check_landmarks", "landmark_map_problems", "print_report", "run_checks"]
