"""Conformance checks for any filter (docs/architecture.md), used by ``beacon-sim check``.

The checks build the filter from a ``FilterContext``, feed it 100 steps of a scenario, and
check: the interface, shapes, finite values, a symmetric positive semi-definite covariance,
a heading in [-pi, pi), that an empty update is accepted, that two runs of the same steps
give bit-identical estimates even when the global ``np.random`` is seeded differently, and
that the filter draws nothing from the global ``np.random`` / ``random`` generators. Each
check is judged on its own (one fault, one FAIL); the report ends with the cost per step
beside the built-in ekf's.

Scenario: when the given scenario has no sensor the filter can use (a filter may say which
kinds it uses in a ``sensor_kinds`` class attribute, e.g. the KF uses pose and position
fixes), the first shipped scenario with such a sensor is used instead, and the report says
so.
"""

from __future__ import annotations

import math
import random
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from beacon_sim.core.scenario import Scenario, load_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.core.types import Step
from beacon_sim.filters.base import (
    Filter,
    FilterContext,
    FilterError,
    GaussianBelief,
    GridBelief,
    ParticleBelief,
)
from beacon_sim.filters.containment import Limits, resolve_sandbox
from beacon_sim.filters.guard import MAX_COV, MAX_MEAN
from beacon_sim.filters.host import call_guarded, guarded_call
from beacon_sim.filters.hosting import hosted_source
from beacon_sim.filters.isolated import FilterChild, IsolatedFilter
from beacon_sim.filters.landmark_check import landmark_map_problems
from beacon_sim.filters.loading import (
    FilterLoadError,
    build_filter,
    build_from_context,
    filter_display_name,
    initial_belief,
    load_filter_class,
    merged_params,
)
from beacon_sim.filters.watchdog import FilterFailed, one_line

N_STEPS = 100
SEED = 12345
#: A step longer than this [s] is a fault ("runs"): a loop that never ends.
STEP_LIMIT_S = 5.0


@dataclass(frozen=True)
class CheckResult:
    """One check: its name, whether it passed, what was seen, and what to fix."""

    name: str
    passed: bool
    message: str = ""
    advice: str = ""


def _scenario_for(host: Any, scenario: Scenario) -> tuple[Scenario, str]:
    kinds = getattr(host, "sensor_kinds", None)
    if not kinds or any(s.kind in kinds for s in scenario.sensors):
        return scenario, ""
    from beacon_sim.core.resources import shipped_scenarios

    for name in shipped_scenarios():
        other = load_scenario(name)
        if any(s.kind in kinds for s in other.sensors):
            return other, (f"scenario {scenario.name} has no {'/'.join(kinds)} sensor; "
                           f"checked on {other.name} instead")
    return scenario, f"no shipped scenario has a {'/'.join(kinds)} sensor"


def _context(scenario: Scenario, spec: str) -> FilterContext:
    from beacon_sim.core.streams import stream

    name = filter_display_name(spec)
    return FilterContext(name=name, world=scenario.filter_world, map_known=scenario.map_known, dt=scenario.dt,
                         motion_noise=scenario.model_motion_noise, sensors=scenario.model_sensors,
                         params=merged_params(spec, scenario),
                         rng=stream(SEED, "filter", name))


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
    the exception that stopped it (step number from 1, ``Type: message``), cost [ns]."""

    estimates: list[object]
    error: tuple[int, str] | None
    step_ns: int


def _feed(flt: Filter, steps: Sequence[Step], limit_s: float) -> _Feed:
    """Feed ``steps`` to ``flt`` (predict, update, estimate each), stopping at the first
    exception or after ``limit_s`` seconds of CPU time in one step (an endless loop)."""
    out: list[object] = []
    ns = 0
    for k, st in enumerate(steps, 1):
        def one(st: Step = st) -> object:
            flt.predict(st.control, st.dt)
            flt.update(st.measurements)
            return flt.estimate()

        t0 = time.perf_counter_ns()
        est, why, _ = call_guarded(one, limit_s, cpu=True,
                                   over=f"time limit: a step took over {limit_s:g} s")
        if why is not None:
            return _Feed(out, (k, why), ns)
        own = getattr(flt, "last_step_ns", None)  # a filter in a child: its own cost there
        ns += own if isinstance(own, int) else time.perf_counter_ns() - t0
        out.append(est)
    return _Feed(out, None, ns)


class _LocalHost:
    """The filter's class in this process (a built-in filter, or ``isolated=False``)."""

    def __init__(self, cls: type):
        self.cls = cls
        self.where = f"{cls.__module__}.{cls.__name__}"
        self.sensor_kinds = getattr(cls, "sensor_kinds", None)
        self.missing = [m for m in ("reset", "predict", "update", "estimate", "belief")
                        if not callable(getattr(cls, m, None))]

    def make(self, scenario: Scenario, spec: str, global_seed: int | None = None) -> Filter:
        """A fresh filter, built and reset (the global RNGs seeded first, when given)."""
        if global_seed is not None:
            np.random.seed(global_seed)  # noqa: NPY002 - the point of the check
            random.seed(global_seed)
        return build_from_context(self.cls, _context(scenario, spec), initial_belief(scenario), spec,
                                  limit_s=STEP_LIMIT_S)

    def drew_global(self) -> tuple[bool, bool] | None:
        return None  # judged from this process's own generators

    def close(self) -> None:
        pass


class _ChildHost:
    """The filter in a child process of its own (a file): its code never runs here."""

    def __init__(self, child: FilterChild, log: Path | None = None, source: Path | None = None):
        self.child = child
        self.log = log  # the child's stdout and stderr
        self.source = source  # the filter's file (read, never run, here), when known
        info = child.info
        self.where = f"{info.get('module', '?')}.{child.class_name} (in a process of its own)"
        self.sensor_kinds = info.get("sensor_kinds")
        self.missing = list(info.get("missing") or [])

    def make(self, scenario: Scenario, spec: str, global_seed: int | None = None) -> Filter:
        return IsolatedFilter(self.child, _context(scenario, spec), initial_belief(scenario),
                              0 if global_seed is None else global_seed, None, spec,
                              step_limit_s=STEP_LIMIT_S, strict_map=False)  # the map check's

    def drew_global(self) -> tuple[bool, bool] | None:
        rep = self.child.end()
        return bool(rep.get("np_global")), bool(rep.get("py_global"))

    def close(self) -> None:
        self.child.close()


_Host = _LocalHost | _ChildHost


def _run(host: _Host, scenario: Scenario, spec: str, steps: Sequence[Step],
         global_seed: int) -> _Feed:
    """Build, reset and feed the steps with the global RNGs seeded."""
    try:
        flt = host.make(scenario, spec, global_seed)
    except Exception as exc:
        return _Feed([], (0, one_line(exc)), 0)
    return _feed(flt, steps, STEP_LIMIT_S)


def _open_host(spec: str, isolated: bool, sandbox: str) -> _Host:
    """Where the checked filter runs: a file in a child process (``isolated``), else here.
    Raises FilterError (the name is no filter: one line, exit status 2) or FilterFailed
    (the file does not import)."""
    where = hosted_source(spec) if isolated else None  # a file or a module filter
    if where is not None:
        path, cls = where
        if isinstance(path, Path) and not path.is_file():
            raise FilterLoadError(f"{path}: no such filter file")
        log = Path(tempfile.mkdtemp(prefix="beacon-sim-check-")) / "log.txt"
        child = FilterChild(path, cls, log, resolve_sandbox(sandbox), Limits(),
                            reply_timeout_s=max(60.0, 4 * STEP_LIMIT_S))
        return _ChildHost(child, log, path if isinstance(path, Path) else path.origin())
    return _LocalHost(load_filter_class(spec))


def _same(a: object, b: object) -> bool:
    """Bit-identical estimates (NaN equal to NaN: a NaN is the finite check's business)."""
    try:
        return all(np.array_equal(np.asarray(x, dtype=float), np.asarray(y, dtype=float),
                                  equal_nan=True) for x, y in zip(a, b, strict=True))  # type: ignore[call-overload]
    except (TypeError, ValueError):
        return repr(a) == repr(b)


def _same_np_state(a: dict[str, Any], b: dict[str, Any]) -> bool:
    """Whether two ``np.random.get_state(legacy=False)`` dicts (MT19937) are the same state."""
    return (a["bit_generator"] == b["bit_generator"]
            and np.array_equal(a["state"]["key"], b["state"]["key"])
            and a["state"]["pos"] == b["state"]["pos"]
            and a["has_gauss"] == b["has_gauss"] and a["gauss"] == b["gauss"])


def _value_problems(estimates: Sequence[object]) -> dict[str, str]:
    """The first step (from 1) failing each value check, judged each on its own: shapes;
    finite (well-shaped estimates); symmetric, positive semi-definite (of the symmetric
    part, so a non-symmetric matrix is still judged) and heading wrapped (finite ones)."""
    problems: dict[str, str] = {}
    for k, est in enumerate(estimates, 1):
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
            problems.setdefault("finite", f"step {k}: a mean beyond {MAX_MEAN:g} or a covariance "
                                f"entry over {MAX_COV:g} (diverged)")
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
    return problems


def _loads_failed(exc: Exception) -> CheckResult:
    """"loads" failed: the name is no filter, or its file does not import."""
    return CheckResult("loads", False, str(exc), "check the spelling: a built-in name, "
                       "pkg.mod:Class or path/to/file.py:Class, and that the file imports "
                       "without errors")


def _result(name: str, passed: object, message: str = "", advice: str = "") -> CheckResult:
    """A CheckResult whose advice is kept only when the check failed."""
    return CheckResult(name, bool(passed), message, "" if passed else advice)


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


def check_constructs(fresh: Callable[[], Filter]) -> tuple[Filter | None, CheckResult]:
    """Is the filter built from a FilterContext and reset? Returns it (None when not)."""
    try:
        flt = fresh()
    except Exception as exc:
        return None, _result("constructs", False, one_line(exc),
                             "the class must take one argument, a FilterContext (call "
                             "super().__init__(ctx) when subclassing FilterBase), and "
                             "reset(initial) must accept a GaussianBelief or None")
    return flt, _result("constructs", True, "built from a FilterContext and reset")


def check_runs(run: _Feed, n_meas: int) -> CheckResult:
    """Did every step (predict, update, estimate) return, within the time limit?"""
    if run.error is None:
        return _result("runs", True, f"{N_STEPS} steps, {n_meas} readings")
    return _result("runs", False, f"step {run.error[0]}: {run.error[1]}",
                   "run `beacon-sim run SCENARIO --filter YOURS` to see the traceback; predict "
                   "and update must accept the Control and the list of Measurement of every "
                   "step, and a step must not loop for ever")


def estimate_problems(after_reset: list[object], estimates: Sequence[object]) -> dict[str, str]:
    """The value problems of the estimate after reset (if any) and of the steps' estimates,
    a shapes fault of the first one said to be "after reset" (see :func:`_value_problems`)."""
    problems = _value_problems(after_reset + list(estimates))
    if after_reset and "shapes" in problems and problems["shapes"].startswith("step 1:"):
        problems["shapes"] = "after reset:" + problems["shapes"][len("step 1:"):]
    return problems


def check_shapes(problems: dict[str, str]) -> CheckResult:
    """Is every estimate a (mean, cov) pair of shapes (3,) and (3, 3)?"""
    return _result("shapes", "shapes" not in problems,
                   problems.get("shapes", "mean (3,), cov (3, 3)"),
                   "estimate() must return (mean, cov) with mean shape (3,) [x, y, theta] and "
                   "cov (3, 3)")


def check_finite(problems: dict[str, str]) -> CheckResult:
    """Is every estimate free of NaN and infinity, and not diverged?"""
    return _result("finite", "finite" not in problems,
                   problems.get("finite", "no NaN or infinity"),
                   "look for a division by a zero range or weight sum, or a covariance that "
                   "was not kept positive definite")


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


def check_belief(flt: Filter) -> CheckResult:
    """Does ``belief()`` return one of the three belief types?"""
    b, why, _ = guarded_call(flt.belief, STEP_LIMIT_S)
    if why is not None:
        return _result("belief", False, why, "belief() must not raise")
    return _result("belief", isinstance(b, GaussianBelief | ParticleBelief | GridBelief),
                   type(b).__name__,
                   "belief() must return a GaussianBelief, ParticleBelief or GridBelief")


def _slam_scenario(scenario: Scenario) -> tuple[Scenario, str]:
    """The scenario the map check runs on: ``scenario`` when its map is withheld, else
    ``slam_loop`` (on a known map a SLAM filter has no landmarks to report)."""
    if not scenario.map_known:
        return scenario, ""
    return load_scenario("slam_loop"), " (on slam_loop: the given scenario's map is known)"


def check_landmarks(host: _Host, scenario: Scenario, spec: str) -> list[CheckResult]:
    """For a SLAM filter (one with ``landmarks()``): after every one of the steps the map is
    well formed (see :func:`landmark_map_problems`); the first step with a fault, one FAIL
    naming every fault of that step. No result for a filter without ``landmarks()``. A filter
    in a process of its own sends its map back with each step's estimate
    (:class:`~beacon_sim.filters.isolated.IsolatedMappingFilter`), judged here the same way."""
    if isinstance(host, _ChildHost):
        if host.child.info.get("landmarks") is not True:
            return []
    elif not callable(getattr(host.cls, "landmarks", None)):
        return []
    used, note = _slam_scenario(scenario)
    advice = ("landmarks() must return LandmarkMap(ids, means, covs): ids None or (M,) ints, "
              "means (M, 2) [m], covs (M, 2, 2) [m^2] symmetric positive semi-definite "
              "(filters/base.py, docs/slam.md)")
    try:
        flt = host.make(used, spec)
    except Exception as exc:
        return [_result("landmarks", False, f"not built on {used.name}: {one_line(exc)}", advice)]
    n_max = 0
    for k, st in enumerate(Simulation(used, SEED).run(N_STEPS * used.dt), 1):
        def one(st: Step = st) -> object:
            flt.predict(st.control, st.dt)
            flt.update(st.measurements)
            return flt.landmarks()  # type: ignore[attr-defined]

        lm, why, _ = call_guarded(one, STEP_LIMIT_S, cpu=True,
                                  over=f"time limit: a step took over {STEP_LIMIT_S:g} s")
        if why is not None:
            return [_result("landmarks", False, f"step {k}{note}: {why}", advice)]
        faults = landmark_map_problems(lm)
        if faults:
            return [_result("landmarks", False, f"step {k}{note}: " + "; ".join(faults), advice)]
        n_max = max(n_max, len(np.asarray(lm.means).reshape(-1, 2)))  # type: ignore[attr-defined]
    return [_result("landmarks", True, f"ids, means (M, 2), covs (M, 2, 2) finite, symmetric, PSD "
                    f"on every step{note}; up to {n_max} landmarks")]


@dataclass
class _EmptyTrial:
    """Two empty updates on a fresh filter: the estimates before and after, why the updates
    failed (``Type: message``) and why the estimate after them failed, or None."""

    before: object
    after: object
    why: str | None
    why_after: str | None


def _empty_trial(fresh: Callable[[], Filter]) -> _EmptyTrial:
    """``update([])`` and ``update(())`` on a fresh filter right after reset."""
    try:
        ef = fresh()
        before, _, _ = guarded_call(ef.estimate, STEP_LIMIT_S)

        def empty() -> None:
            ef.update([])
            ef.update(())

        _, why, _ = guarded_call(empty, STEP_LIMIT_S)
        after, why_after, _ = guarded_call(ef.estimate, STEP_LIMIT_S)
    except Exception as exc:
        return _EmptyTrial(None, None, one_line(exc), None)
    return _EmptyTrial(before, after, why, why_after)


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


def blame_one_fault(runs: CheckResult, empty: CheckResult, run: _Feed, trial: _EmptyTrial,
                    steps: Sequence[Step],
                    fresh: Callable[[], Filter]) -> tuple[CheckResult, CheckResult]:
    """One fault seen twice ("runs" and "empty update" failing with the same error): blame
    the empty update only if an update with readings works, else "runs" only. Returns the
    two results, changed or not."""
    if run.error is None or empty.passed or trial.why != run.error[1]:
        return runs, empty
    with_readings = next((st for st in steps if st.measurements), None)
    try:
        probe = fresh()
        ok = with_readings is not None and _feed(probe, [with_readings], STEP_LIMIT_S).error is None
    except Exception:
        ok = False
    if ok:
        return CheckResult("runs", True, f"stopped at step {run.error[0]}, a step without "
                           "readings: the empty update fault below"), empty
    return runs, CheckResult("empty update", True, "not judged: update fails with readings too "
                             "(see runs)")


@dataclass
class _RngTrial:
    """Two runs of the same steps with the global RNGs seeded 1 and 2, and whether the first
    drew from the global ``np.random`` / ``random`` generators."""

    run1: _Feed
    run2: _Feed
    drew_np: bool
    drew_py: bool


def _rng_trial(host: _Host, scenario: Scenario, spec: str, steps: Sequence[Step]) -> _RngTrial:
    """Run twice with the global RNGs seeded differently; their states are restored after."""
    state_np = np.random.get_state(legacy=False)  # noqa: NPY002
    state_py = random.getstate()
    try:
        np.random.seed(1)  # noqa: NPY002
        random.seed(1)
        ref_np = np.random.get_state(legacy=False)  # noqa: NPY002
        ref_py = random.getstate()
        run1 = _run(host, scenario, spec, steps, 1)
        now_np = np.random.get_state(legacy=False)  # noqa: NPY002
        drew_np = not _same_np_state(now_np, ref_np)
        drew_py = random.getstate() != ref_py
        try:
            child_drew = host.drew_global()
        except FilterFailed:
            child_drew = None
        if child_drew is not None:
            drew_np, drew_py = child_drew
        run2 = _run(host, scenario, spec, steps, 2)
    finally:
        np.random.set_state(state_np)  # noqa: NPY002
        random.setstate(state_py)
    return _RngTrial(run1, run2, drew_np, drew_py)


def check_determinism(trial: _RngTrial) -> CheckResult:
    """Are the estimates bit-identical when only the global np.random seed changes?"""
    run1, run2 = trial.run1, trial.run2
    diff_at = next((k for k, (a, b) in enumerate(zip(run1.estimates, run2.estimates, strict=False), 1)
                    if not _same(a, b)), None)
    if diff_at is None and (run1.error is None) != (run2.error is None):
        diff_at = min(len(run1.estimates), len(run2.estimates)) + 1
    return _result("deterministic", diff_at is None,
                   "same estimates bit for bit with the global RNG seeded 1 and 2" if diff_at is None
                   else f"estimates differ from step {diff_at} when only the global np.random "
                   "seed changes",
                   "draw random numbers only from ctx.rng (a numpy Generator), never from "
                   "np.random.* or random.*")


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


def report_cost(run: _Feed, scenario: Scenario, steps: Sequence[Step]) -> CheckResult:
    """The cost per step [us] beside the built-in ekf's on the same steps (not a check)."""
    mine = run.step_ns / 1e3 / max(len(run.estimates), 1)
    ref = _feed(build_filter("ekf", scenario, SEED), steps, STEP_LIMIT_S)
    ekf_us = ref.step_ns / 1e3 / max(len(ref.estimates), 1)
    return _result("cost", True, f"{mine:.1f} us per step (predict + update + estimate); the "
                   f"built-in ekf: {ekf_us:.1f} us on the same steps "
                   f"({mine / max(ekf_us, 1e-9):.1f}x)")


def report_output(host: _Host) -> list[CheckResult]:
    """Where the filter's printed output went, if it printed anything (not a check)."""
    log = getattr(host, "log", None)
    if log is not None and log.exists() and log.stat().st_size:
        return [_result("output", True, f"the filter printed {log.stat().st_size} bytes: see {log}")]
    return []


def run_checks(spec: str, scenario: Scenario, *, isolated: bool = True,
               sandbox: str = "auto") -> list[CheckResult]:
    """Run every check on the filter named ``spec`` with ``scenario``'s map and sensors.

    A filter file runs in a child process of its own (``isolated``, the default; ``sandbox``
    as for ``grade``): its code never runs in this process, and a filter that exits, loops
    or raises ``KeyboardInterrupt`` fails a check instead of ending the program.

    Each check stands on its own, so one fault gives one FAIL: a filter that raises at step
    k fails "runs" and is judged by the other checks on the steps before k; a NaN fails
    "finite" only (the determinism check counts NaN equal to NaN, the empty update check
    only asks that an empty update neither raises nor spoils a usable estimate). The last
    line is the cost per step beside the built-in ekf's on the same steps (not a check).
    """
    try:
        host = _open_host(spec, isolated, sandbox)
    except (FilterError, FilterFailed) as exc:
        return [_loads_failed(exc)]
    results: list[CheckResult] = []
    try:
        results += _checks(host, spec, scenario)
    finally:
        host.close()
        results += report_output(host)
    return results


def _checks(host: _Host, spec: str, scenario: Scenario) -> list[CheckResult]:
    """The checks after the filter loaded, in order (see :func:`run_checks`); the list stops
    after "interface" or "constructs" when that one fails."""
    results = [check_loads(host)]
    scenario, notes = check_scenario(host, scenario)
    results += notes
    results.append(check_interface(host))
    if not results[-1].passed:
        return results

    def fresh() -> Filter:
        return host.make(scenario, spec)

    flt, constructs = check_constructs(fresh)
    results.append(constructs)
    if flt is None:
        return results

    steps = Simulation(scenario, SEED).run(N_STEPS * scenario.dt)
    n_meas = sum(len(m) for s in steps for m in s.measurements)
    est0, why0, _ = guarded_call(flt.estimate, STEP_LIMIT_S)
    run = _feed(flt, steps, STEP_LIMIT_S)
    runs = check_runs(run, n_meas)
    problems = estimate_problems([] if why0 else [est0], run.estimates)
    values = [check_shapes(problems), check_finite(problems), check_covariance_symmetric(problems),
              check_covariance_psd(problems), check_heading_wrapped(problems)]
    belief = check_belief(flt)  # on a filter that ran the steps it could
    trial = _empty_trial(fresh)  # a fresh filter right after reset: no other fault shown yet
    runs, empty = blame_one_fault(runs, check_empty_update(trial), run, trial, steps, fresh)
    rng = _rng_trial(host, scenario, spec, steps)
    return [*results, runs, *values, belief, *check_landmarks(host, scenario, spec), empty,
            check_determinism(rng), check_global_rng(rng), report_cost(run, scenario, steps)]


def print_report(spec: str, results: list[CheckResult]) -> None:
    """One line per check, then what to fix for each failure."""
    print(f"conformance of {spec}:")
    width = max((len(r.name) for r in results), default=0)
    for r in results:
        mark = "PASS" if r.passed else "FAIL"
        print(f"  {mark}  {r.name:<{width}}  {r.message}")
    failed = [r for r in results if not r.passed]
    if failed:
        print("what to fix:")
        for r in failed:
            print(f"  - {r.name}: {r.advice}")
    print(f"{len(results) - len(failed)} of {len(results)} checks passed")
