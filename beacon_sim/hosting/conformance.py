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

Scenario: when the given scenario has no sensor the filter can use (a filter may say which
kinds it uses in a ``sensor_kinds`` class attribute, e.g. the KF uses pose and position
fixes), the first shipped scenario with such a sensor is used instead, and the report says
so.
"""

from __future__ import annotations

import math
import pickle
import secrets
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from beacon_sim.core.metrics import pose_errors
from beacon_sim.core.scenario import Scenario, load_scenario
from beacon_sim.core.sensor_kinds import scan_sensors
from beacon_sim.core.simulation import Simulation
from beacon_sim.core.streams import keyed_global_seed, keyed_stream, run_key
from beacon_sim.filters.base import FilterContext, FilterError
from beacon_sim.hosting.client import FilterChild, start_child, step_request
from beacon_sim.hosting.containment import resolve_sandbox
from beacon_sim.hosting.feed import (
    GRADE_RUN_S,
    GRADE_SEEDS,
    GRADE_TIME_LIMIT_S,
    PROBE_TICKS,
    Fed,
    LocalChild,
    ProbeFindings,
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
from beacon_sim.hosting.guard import DIVERGED, MAX_COV, MAX_MEAN, NEES_NOT_FINITE
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


@dataclass(frozen=True)
class CheckResult:
    """One check: its name, whether it passed, what was seen, and what to fix."""

    name: str
    passed: bool
    message: str = ""
    advice: str = ""
    #: False: nothing to judge it on (the filter never got that far): printed "SKIP", not
    #: "PASS", and not counted as passed.
    judged: bool = True
    #: Not a check at all (the cost, where the output went): printed "NOTE", not counted.
    note: bool = False

    @property
    def mark(self) -> str:
        """How the report marks it: PASS, FAIL, SKIP (not judged) or NOTE (not a check)."""
        if self.note:
            return "NOTE"
        if not self.passed:
            return "FAIL"
        return "PASS" if self.judged else "SKIP"


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


def _estimate_problem(est: object) -> str | None:
    """What is wrong with the form of an ``estimate()`` result (a pair of arrays of numbers
    of shapes (3,) and (3, 3)), or None. Values are judged by the separate checks."""
    if not isinstance(est, tuple | list) or len(est) != 2:
        return f"estimate() returned {type(est).__name__}, expected a (mean, cov) pair"
    try:
        mean = np.asarray(est[0], dtype=float)
        cov = np.asarray(est[1], dtype=float)
    except (TypeError, ValueError):
        return "estimate() returned something that is not arrays of numbers"
    if mean.shape != (3,) or cov.shape != (3, 3):
        return f"shapes {mean.shape} and {cov.shape}, expected (3,) and (3, 3)"
    return None


@dataclass
class _Feed:
    """One pass of a filter over the steps: the estimates of the steps that returned,
    the failure that stopped it (step number from 1, its one line), cost [ns]."""

    estimates: list[object]
    error: tuple[int, str] | None
    step_ns: int


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


def _value_problems(estimates: Sequence[object], truths: np.ndarray | None = None) -> dict[str, str]:
    """The first step (from 1) failing each value check, judged each on its own: shapes;
    finite (well-shaped estimates: no NaN or infinity, not diverged by the guard's rule,
    and, with the ``truths`` (T, 3) of the steps, a finite NEES); symmetric, positive
    semi-definite (of the symmetric part, so a non-symmetric matrix is still judged) and
    heading wrapped (finite ones). Nothing after the first estimate that is not finite is
    judged: ``grade`` and ``run`` stop the filter there, and what a diverged filter returns
    next (a covariance with rounding errors of 1e9) is no fault of its own."""
    problems: dict[str, str] = {}
    for k, est in enumerate(estimates, 1):
        if "finite" in problems:
            break
        p = _estimate_problem(est)
        if p:
            problems.setdefault("shapes", f"step {k}: {p}")
            continue
        pair: Any = est
        mean = np.asarray(pair[0], dtype=np.float64)
        cov = np.asarray(pair[1], dtype=np.float64)
        if not (np.all(np.isfinite(mean)) and np.all(np.isfinite(cov))):
            problems.setdefault("finite", f"step {k}: NaN or infinity in the estimate")
            continue
        scale = max(float(np.max(np.abs(cov))), 1e-12)
        if scale > MAX_COV or float(np.max(np.abs(mean))) > MAX_MEAN:  # the guard's "diverged"
            problems.setdefault("finite", f"step {k}: {DIVERGED}")
            continue
        asym = float(np.max(np.abs(cov - cov.T)))
        if asym > 1e-9 * scale:
            problems.setdefault("symmetric", f"step {k}: cov - cov^T up to {asym:.3g}")
        try:
            low = float(np.min(np.linalg.eigvalsh(0.5 * (cov + cov.T))))
        except np.linalg.LinAlgError:
            low = -math.inf
        if low < -1e-9 * scale:
            problems.setdefault("psd", f"step {k}: smallest eigenvalue {low:.3g}")
        if not -math.pi <= mean[2] < math.pi:
            problems.setdefault("heading", f"step {k}: theta = {mean[2]!r}")
        if truths is not None and k <= len(truths) and "finite" not in problems:
            err = pose_errors(mean, truths[k - 1])[0]
            with np.errstate(all="ignore"):
                try:
                    value = float(err @ np.linalg.solve(cov, err))
                except np.linalg.LinAlgError:
                    value = math.inf
            if not math.isfinite(value):
                problems["finite"] = f"step {k}: {NEES_NOT_FINITE}"
    return problems


def _loads_failed(exc: Exception) -> CheckResult:
    """"loads" failed: the name is no filter, or its file does not import."""
    return CheckResult("loads", False, str(exc), "check the spelling: a built-in name, "
                       "pkg.mod:Class or path/to/file.py:Class, and that the file imports "
                       "without errors")


def _result(name: str, passed: object, message: str = "", advice: str = "", *,
            note: bool = False) -> CheckResult:
    """A CheckResult whose advice is kept only when the check failed; a passing one whose
    message says "not judged" was not judged (SKIP); ``note``: not a check (NOTE)."""
    judged = not (passed and message.startswith("not judged"))
    return CheckResult(name, bool(passed), message, "" if passed else advice, judged, note)


#: What a check that had nothing to judge says when no step of any run returned.
NO_STEP = "not judged: no step returned an estimate (see runs)"


def check_loads(host: _Host) -> CheckResult:
    """Does the filter load? (It did, when there is a host: say where it came from.)"""
    return _result("loads", True, host.where)


def check_scenario(host: _Host, scenario: Scenario) -> tuple[Scenario, list[CheckResult]]:
    """Which scenario the filter is checked on, and a note when it is not the given one."""
    used, note = _scenario_for(host, scenario)
    return used, ([_result("scenario", True, note)] if note else [])


def check_interface(host: _Host) -> CheckResult:
    """Does the class have the five methods of ``beacon_sim.filters.base.Filter``?"""
    missing = host.missing
    return _result("interface", not missing,
                   f"missing: {', '.join(missing)}" if missing
                   else "reset, predict, update, estimate, belief",
                   "implement every method of beacon_sim.filters.base.Filter (subclass "
                   "FilterBase to get belief() for free)")


def check_constructs(why: str | None) -> CheckResult:
    """Was the filter built from a FilterContext and reset (``why``: why not)?"""
    if why is not None:
        return _result("constructs", False, why.removeprefix("construction failed: "),
                       "the class must take one argument, a FilterContext (call "
                       "super().__init__(ctx) when subclassing FilterBase), and "
                       "reset(initial) must accept a GaussianBelief or None")
    return _result("constructs", True, "built from a FilterContext and reset")


def check_runs(run: _Feed, n_meas: int, note: str = "") -> CheckResult:
    """Did every step (predict, update, estimate) return, within the run's time limit?"""
    if run.error is None:
        return _result("runs", True, f"{len(run.estimates)} steps, {n_meas} readings{note}")
    return _result("runs", False, f"step {run.error[0]}: {run.error[1]}", RUNS_ADVICE)


RUNS_ADVICE = ("run `beacon-sim run SCENARIO --filter YOURS` to see the traceback; predict and update "
               "must accept the Control and the list of Measurement of every step, and a run must stay "
               "within its time limit")


def estimate_problems(after_reset: list[object], estimates: Sequence[object],
                      truths: np.ndarray | None = None) -> dict[str, str]:
    """The value problems of the estimate after reset (if any, said to be "after reset") and
    of the steps' estimates (see :func:`_value_problems`; ``truths``: the steps' true poses,
    for the NEES); the earlier one of each kind wins."""
    problems = {k: "after reset:" + v.removeprefix("step 1:")
                for k, v in _value_problems(after_reset).items()}
    for k, v in _value_problems(estimates, truths).items():
        problems.setdefault(k, v)
    return problems


def check_shapes(problems: dict[str, str]) -> CheckResult:
    """Is every estimate a (mean, cov) pair of shapes (3,) and (3, 3)?"""
    return _result("shapes", "shapes" not in problems,
                   problems.get("shapes", "mean (3,), cov (3, 3)"),
                   "estimate() must return (mean, cov) with mean shape (3,) [x, y, theta] and "
                   "cov (3, 3)")


def check_finite(problems: dict[str, str]) -> CheckResult:
    """Is every estimate free of NaN and infinity, not diverged, and its covariance one that
    leaves room for its error (a finite NEES)?"""
    return _result("finite", "finite" not in problems,
                   problems.get("finite", "no NaN or infinity, not diverged, a finite NEES"),
                   "look for a division by a zero range or weight sum, a covariance that was not "
                   "kept positive definite, one that grows without bound, or one that rules out "
                   "the error it has (a zero variance)")


def check_covariance_symmetric(problems: dict[str, str]) -> CheckResult:
    """Is every covariance symmetric?"""
    return _result("symmetric covariance", "symmetric" not in problems,
                   problems.get("symmetric", "cov == cov^T"),
                   "symmetrise after the update (P = (P + P^T) / 2) or use the Joseph form "
                   "(I - KH) P (I - KH)^T + K R K^T")


def check_covariance_psd(problems: dict[str, str]) -> CheckResult:
    """Is every covariance positive semi-definite?"""
    return _result("positive semi-definite covariance", "psd" not in problems,
                   problems.get("psd", "no negative eigenvalue"),
                   "use the Joseph form for the covariance update; P - K S K^T loses "
                   "definiteness through rounding")


def check_heading_wrapped(problems: dict[str, str]) -> CheckResult:
    """Is every heading in [-pi, pi)?"""
    return _result("heading wrapped", "heading" not in problems,
                   problems.get("heading", "in [-pi, pi)"),
                   "wrap the heading after predict and update with beacon_sim.core.angles.wrap, "
                   "and wrap every angle residual with angles.diff")


def check_belief(why: str | None) -> CheckResult:
    """Did ``belief()`` (asked at the end of the run) return one of the three belief types
    (``why``: what was wrong; "not asked": the run failed before)?"""
    if why == "not asked":
        return _result("belief", True, "not judged: the filter failed before (see above)")
    return _result("belief", why is None, why or "a GaussianBelief, ParticleBelief or GridBelief",
                   "belief() must return a GaussianBelief, ParticleBelief or GridBelief and must "
                   "not raise")


LANDMARKS_ADVICE = ("landmarks() must return LandmarkMap(ids, means, covs): ids None or (M,) ints, "
                    "means (M, 2) [m], covs (M, 2, 2) [m^2] symmetric positive semi-definite "
                    "(filters/base.py, docs/slam.md)")


def _slam_scenario(scenario: Scenario) -> tuple[Scenario, str]:
    """The scenario the map check runs on: ``scenario`` when its map is withheld, else
    ``slam_loop`` (on a known map a SLAM filter has no landmarks to report)."""
    if not scenario.map_known:
        return scenario, ""
    return load_scenario("slam_loop"), " (on slam_loop: the given scenario's map is known)"


def check_landmarks(fed: Fed, k: int, note: str) -> CheckResult:
    """Was the SLAM filter's map (slot k of ``fed``, judged on every step as ``grade`` judges
    it) well formed? The first step with a fault, one FAIL naming it."""
    why = fed.failed[k]
    if why is not None and why.startswith("landmarks()"):
        return _result("landmarks", False, f"step {int(fed.failed_at[k] or 0) + 1}{note}: {why}",
                       LANDMARKS_ADVICE)
    if why is not None and fed.done(k) == 0:
        return _result("landmarks", False, f"not run{note}: {why}", LANDMARKS_ADVICE)
    n = 0 if fed.maps[k] is None else len(fed.maps[k][1])
    return _result("landmarks", True, f"ids, means (M, 2), covs (M, 2, 2) finite, symmetric, PSD "
                   f"on every step{note}; up to {n} landmarks")


@dataclass
class _EmptyTrial:
    """An update without readings on a fresh filter: the estimates before it (after
    predict) and after it, why the step failed (``Type: message``) and why the estimate
    after it failed, or None."""

    before: object
    after: object
    why: str | None
    why_after: str | None


def check_empty_update(trial: _EmptyTrial) -> CheckResult:
    """Is an empty update accepted without spoiling a usable estimate?"""
    if trial.why_after is not None:
        return _result("empty update", True, "not judged: the filter failed before (see above)")
    if trial.why is not None:
        return _result("empty update", False, trial.why, "update([]) happens on every tick "
                       "without readings: return early when the list is empty")
    before, after = trial.before, trial.after
    usable_before = _estimate_problem(before) is None and not _value_problems([before])
    spoilt = usable_before and bool(_estimate_problem(after) or _value_problems([after]))
    moved = not spoilt and not _same(before, after)
    return _result("empty update", not spoilt,
                   "spoils the estimate" if spoilt
                   else ("accepted" + ("; the mean moved" if moved else "")),
                   "update([]) happens on every tick without readings: return without "
                   "changing the belief")


def _same(a: object, b: object) -> bool:
    """Bit-identical estimates (NaN equal to NaN: a NaN is the finite check's business)."""
    try:
        return all(np.array_equal(np.asarray(x, dtype=float), np.asarray(y, dtype=float),
                                  equal_nan=True) for x, y in zip(a, b, strict=True))  # type: ignore[call-overload]
    except (TypeError, ValueError):
        return repr(a) == repr(b)


@dataclass
class _RngTrial:
    """The run and its copy fed again in the same batch (``run1``, ``run2``; ``others``: the
    run with its readings drawn again and its copy), and whether the batch drew from the
    global ``np.random`` / ``random`` generators."""

    run1: _Feed
    run2: _Feed
    drew_np: bool
    drew_py: bool
    others: tuple[_Feed, _Feed] | None = None
    #: The probes' own verdict (:func:`~beacon_sim.hosting.feed.judge_probes`: which tick
    #: was answered, and why each stopped), when there is one: it decides.
    judged: ProbeFindings | None = None


def _first_difference(run1: _Feed, run2: _Feed) -> int | None:
    at = next((k for k, (a, b) in enumerate(zip(run1.estimates, run2.estimates, strict=False), 1)
               if not _same(a, b)), None)
    if at is None and (run1.error is None) != (run2.error is None):
        at = min(len(run1.estimates), len(run2.estimates)) + 1
    return at


def check_determinism(trial: _RngTrial) -> CheckResult:
    """Are the estimates bit-identical when the same run is fed again?"""
    if trial.judged is not None and trial.judged.deterministic is not None:
        diff_at = trial.judged.differs_at if not trial.judged.deterministic else None
    else:
        pairs = [(trial.run1, trial.run2)] + ([trial.others] if trial.others is not None else [])
        diffs = [d for d in (_first_difference(a, b) for a, b in pairs) if d is not None]
        diff_at = min(diffs) if diffs else None
    return _result("deterministic", diff_at is None,
                   "the same run fed again gives the same estimates bit for bit" if diff_at is None
                   else f"estimates differ from step {diff_at} when the same run is fed again",
                   "draw random numbers only from ctx.rng (a numpy Generator), never from "
                   "np.random.* or random.*, and nothing from the clock, object ids or set order")


def check_global_rng(trial: _RngTrial) -> CheckResult:
    """Did the filter leave the global np.random and random generators untouched?"""
    drew_np, drew_py = trial.drew_np, trial.drew_py
    return _result("no global RNG", not (drew_np or drew_py),
                   "the global np.random and random states were left untouched"
                   if not (drew_np or drew_py)
                   else "the filter drew from the global "
                   + ("np.random" if drew_np else "random") + " generator",
                   "replace np.random.normal(...) / np.random.rand(...) by "
                   "self.ctx.rng.normal(...) / self.ctx.rng.random(...) (store ctx.rng in "
                   "__init__)")


def cost_peer(scenario: Scenario, mapping: bool = False) -> str:
    """The built-in filter whose cost a filter's is set beside: one of its own kind doing the
    same task (``ekf_slam`` for a SLAM filter or a withheld map, ``mcl`` on a map world with
    a range finder, else ``ekf``): a ratio to a filter with another task says nothing."""
    if mapping or not scenario.map_known:
        return "ekf_slam"
    if scan_sensors(scenario.sensors):
        return "mcl"
    return "ekf"


def report_cost(run: _Feed, scenario: Scenario, frames: Sequence[bytes],
                mapping: bool = False) -> CheckResult:
    """The cost per step [us] over ``run``'s steps beside that of the built-in peer of its
    kind (:func:`cost_peer`) fed ``frames`` (the first run's steps) in this process. Not a
    check (a NOTE); nothing to report when no step ran."""
    if not run.estimates:
        return _result("cost", True, "no step ran: no cost to report", note=True)
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
        return _result("cost", True, own, note=True)
    if ref.failed[0] is not None or not ref.done(0):
        return _result("cost", True, own, note=True)
    peer_us = float(ref.walls[:, 0].sum()) / 1e3 / max(ref.done(0), 1)
    return _result("cost", True, f"{own}; the built-in {peer}: {peer_us:.1f} us on the same steps "
                   f"({mine / max(peer_us, 1e-9):.1f}x)", note=True)


def report_output(host: _Host) -> list[CheckResult]:
    """Where the filter's printed output went, if it printed anything (not a check)."""
    log = host.log
    if log is not None and log.exists() and log.stat().st_size:
        return [_result("output", True, f"the filter printed {log.stat().st_size} bytes: see {log}",
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
        return [_loads_failed(exc)]
    results: list[CheckResult] = []
    try:
        chosen = [secrets.randbelow(2**63) for _ in range(GRADE_SEEDS)] if seeds is None else list(seeds)
        results += _checks(host, spec, scenario, [int(s) for s in chosen])
    finally:
        host.close()
        results += report_output(host)
    return results


def _fed_feed(fed: Fed, k: int, ticks: int | None = None) -> _Feed:
    """Slot k of ``fed`` as a :class:`_Feed` (its first ``ticks`` ticks)."""
    n = fed.done(k) if ticks is None else min(fed.done(k), ticks)
    est: list[object] = [(fed.store[i, k, 12:15].copy(), fed.store[i, k, 15:24].reshape(3, 3).copy())
                         for i in range(n)]
    err = None
    if fed.failed[k] is not None and (ticks is None or int(fed.failed_at[k] or 0) < ticks):
        err = (int(fed.failed_at[k] or 0) + 1, fed.failed[k] or "")
    return _Feed(est, err, int(fed.walls[:n, k].sum()))


def _judge_run(fed: Fed, k: int, run: _Run) -> tuple[_Feed, dict[str, str], str]:
    """Run k of ``fed`` (simulated as ``run``) judged: its steps (with the failure that
    ended it, unless that was an estimate's form, a "shapes" problem, or its map, the
    "landmarks" check's), its value problems, and what to add to "runs"' message."""
    feed = _fed_feed(fed, k)
    first = fed.first[k]
    after_reset: list[object] = [first] if isinstance(first, tuple) else []
    problems = estimate_problems(after_reset, feed.estimates, run.truth[1:])
    failure, note = feed.error, ""
    if failure is not None and failure[1].startswith("landmarks()"):
        feed = _Feed(feed.estimates, None, feed.step_ns)
        note = f"; stopped at step {failure[0]} by its map: see landmarks"
    elif failure is not None and failure[1].startswith(("estimate() returned", "after predict: estimate()")):
        problems.setdefault("shapes", f"step {failure[0]}: {failure[1].removeprefix('after predict: ')}")
        feed = _Feed(feed.estimates, None, feed.step_ns)  # every step returned: its form is "shapes"
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
        runs = _result("runs", True, f"{R} run{'s' if R > 1 else ''} of {ticks} steps, {n_meas} readings "
                       f"(seed{'s' if R > 1 else ''} {seeds_text}){''.join(j[2] for j in judged)}")
        empty = _result("empty update", True, "accepted on the "
                        f"{sum(1 for run in sims for h in run.has_readings if not h)} ticks without readings")
    else:
        err = judged[failing][0].error
        assert err is not None
        runs = _result("runs", False, _in_run(failing, sims[failing], f"step {err[0]}: {err[1]}"),
                       RUNS_ADVICE)
        runs, empty = _empty_update(host, fed, failing, sims[failing], runs, slots[failing])
    pf = judge_probes(fed, 0, probes, any(ex.has_readings))
    for what, (why, at) in pf.failures.items():  # the probes are runs too: failing one fails "runs"
        if runs.passed and empty.passed and what != "again":  # ("again": not deterministic)
            runs = _result("runs", False, f"one more run (seed {ex.seed}), step {at + 1}: {why}", RUNS_ADVICE)
    values = [check_shapes(problems), check_finite(problems), check_covariance_symmetric(problems),
              check_covariance_psd(problems), check_heading_wrapped(problems)]
    stepped = any(j[0].estimates for j in judged)
    if not stepped and not problems:  # nothing to judge: say so
        values = [_result(v.name, True, NO_STEP) for v in values]
    belief_fault = next((r for r in range(R) if fed.beliefs[r] not in (None, "not asked")), None)
    belief = check_belief(fed.beliefs[0] if belief_fault is None
                          else _in_run(belief_fault, sims[belief_fault], fed.beliefs[belief_fault] or ""))
    landmarks = _landmarks(host, fed, scenario, spec, secret, seeds)
    k_again = probes["again"]
    horizon = fed.done(k_again) + (fed.failed[k_again] is not None)
    again = _fed_feed(fed, probes["again"]) if "again" in probes else _Feed([], None, 0)
    rng = _RngTrial(_fed_feed(fed, 0, horizon), again, bool(fed.report.get("np_global")),
                    bool(fed.report.get("py_global")), None, pf)
    readings = [] if pf.readings_used is not False else [_result(
        "readings", True, "the estimates do not change when the readings are drawn again: the "
        "filter uses none of them (grade says so too)", note=True)]
    steps = [j[0] for j in judged]
    cost = _Feed([e for f in steps for e in f.estimates], None, sum(f.step_ns for f in steps))
    after = [belief, *landmarks, empty, check_determinism(rng), check_global_rng(rng)]
    if not stepped:  # a filter that never ran a step passes nothing it was not asked (FAILs stay)
        after = [r if not r.passed else _result(r.name, True, NO_STEP) for r in after]
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
        return runs, _result("empty update", True, f"accepted on the {n} ticks without readings before")
    _, control, dt, meas, _want = pickle.loads(run.frames[k][4:])
    empty = step_request(control, dt, meas, True)
    with_readings = next((f for f, h in zip(run.frames, run.has_readings, strict=True) if h), None)
    slots = [Slot(main.ctx, main.initial, [empty], 1, main.spec)]
    if with_readings is not None:
        slots.append(Slot(main.ctx, main.initial, [with_readings], 1, main.spec))
    trial = feed_batch(host.child, slots, RUN_LIMIT_S, keyed_global_seed(run.key, main.spec))
    if not trial.built[0]:
        return runs, _result("empty update", True, "not judged: the filter failed before (see above)")
    ok_with_readings = len(slots) > 1 and trial.failed[1] is None
    if trial.failed[0] is not None:
        if ok_with_readings:
            return (CheckResult("runs", True, _in_run(r, run, f"stopped at step {k + 1}, a step without "
                                                      "readings: the empty update fault below")),
                    check_empty_update(_EmptyTrial(None, None, trial.failed[0], None)))
        return runs, CheckResult("empty update", True, "not judged: update fails with readings too "
                                 "(see runs)")
    store = trial.store[0, 0]
    before = (store[0:3].copy(), store[3:12].reshape(3, 3).copy())
    after = (store[12:15].copy(), store[15:24].reshape(3, 3).copy())
    return runs, check_empty_update(_EmptyTrial(before, after, None, None))


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
        return [_result("landmarks", False, f"not built on {used.name}: {own.failed[0]}", LANDMARKS_ADVICE)]
    return [check_landmarks(own, 0, note)]


def print_report(spec: str, results: list[CheckResult]) -> None:
    """One line per check, then what to fix for each failure."""
    print(f"conformance of {spec}:")
    width = max((len(r.name) for r in results), default=0)
    for r in results:
        print(f"  {r.mark}  {r.name:<{width}}  {r.message}")
    failed = [r for r in results if not r.passed]
    if failed:
        print("what to fix:")
        for r in failed:
            print(f"  - {r.name}: {r.advice}")
    checks = [r for r in results if not r.note]
    skipped = sum(1 for r in checks if r.mark == "SKIP")
    passed = sum(1 for r in checks if r.mark == "PASS")
    print(f"{passed} of {len(checks)} checks passed"
          + (f"; {skipped} not judged (the filter never got that far)" if skipped else ""))


__all__ = ["CheckResult", "check_landmarks", "landmark_map_problems", "print_report", "run_checks"]
