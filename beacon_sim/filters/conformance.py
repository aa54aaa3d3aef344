"""Conformance checks for any filter (docs/architecture.md), used by ``beacon-sim check``.

The checks build the filter from a ``FilterContext``, feed it 100 steps of a scenario, and
check: the interface, shapes, finite values, a symmetric positive semi-definite covariance,
a heading in [-pi, pi), that an empty update is accepted, that two runs of the same steps
give bit-identical estimates even when the global ``np.random`` is seeded differently, and
that the filter draws nothing from the global ``np.random`` / ``random`` generators.

Scenario: when the given scenario has no sensor the filter can use (a filter may say which
kinds it uses in a ``sensor_kinds`` class attribute, e.g. the KF uses pose and position
fixes), the first shipped scenario with such a sensor is used instead, and the report says
so.
"""

from __future__ import annotations

import math
import random
from collections.abc import Sequence
from dataclasses import dataclass
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
from beacon_sim.filters.loading import filter_display_name, load_filter_class, merged_params, reset_filter

N_STEPS = 100
SEED = 12345


@dataclass(frozen=True)
class CheckResult:
    """One check: its name, whether it passed, what was seen, and what to fix."""

    name: str
    passed: bool
    message: str = ""
    advice: str = ""


def _scenario_for(cls: type, scenario: Scenario) -> tuple[Scenario, str]:
    kinds = getattr(cls, "sensor_kinds", None)
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
    return FilterContext(name=name, world=scenario.world, dt=scenario.dt,
                         motion_noise=scenario.model_motion_noise, sensors=scenario.model_sensors,
                         params=merged_params(spec, scenario),
                         rng=stream(SEED, "filter", name))


def _estimate_problem(est: tuple[object, object]) -> str | None:
    """What is wrong with an ``estimate()`` result, or None (a student's filter may return
    anything, whatever its annotation says)."""
    try:
        mean, cov = est
    except (TypeError, ValueError):
        return f"estimate() returned {type(est).__name__}, expected a (mean, cov) pair"
    mean = np.asarray(mean)
    cov = np.asarray(cov)
    if mean.shape != (3,) or cov.shape != (3, 3):
        return f"shapes {mean.shape} and {cov.shape}, expected (3,) and (3, 3)"
    if not (np.all(np.isfinite(mean)) and np.all(np.isfinite(cov))):
        return "NaN or infinity in the estimate"
    return None


def _run(cls: type, scenario: Scenario, spec: str, steps: Sequence[Step],
         global_seed: int) -> tuple[Filter, list[tuple[np.ndarray, np.ndarray]]]:
    """Build, reset and feed the steps with the global RNGs seeded; return the estimates."""
    np.random.seed(global_seed)  # noqa: NPY002 - the point of the check
    random.seed(global_seed)
    flt: Filter = cls(_context(scenario, spec))
    reset_filter(flt, scenario)
    out = []
    for st in steps:
        flt.predict(st.control, st.dt)
        flt.update(st.measurements)
        mean, cov = flt.estimate()
        out.append((np.array(mean, dtype=float), np.array(cov, dtype=float)))
    return flt, out


def _same_np_state(a: dict[str, Any], b: dict[str, Any]) -> bool:
    """Whether two ``np.random.get_state(legacy=False)`` dicts (MT19937) are the same state."""
    return (a["bit_generator"] == b["bit_generator"]
            and np.array_equal(a["state"]["key"], b["state"]["key"])
            and a["state"]["pos"] == b["state"]["pos"]
            and a["has_gauss"] == b["has_gauss"] and a["gauss"] == b["gauss"])


def run_checks(spec: str, scenario: Scenario) -> list[CheckResult]:
    """Run every check on the filter named ``spec`` with ``scenario``'s map and sensors."""
    results: list[CheckResult] = []

    def add(name: str, passed: object, message: str = "", advice: str = "") -> bool:
        results.append(CheckResult(name, bool(passed), message, "" if passed else advice))
        return bool(passed)

    try:
        cls = load_filter_class(spec)
    except FilterError as exc:
        add("loads", False, str(exc), "check the spelling: a built-in name, pkg.mod:Class or "
            "path/to/file.py:Class, and that the file imports without errors")
        return results
    add("loads", True, f"{cls.__module__}.{cls.__name__}")

    scenario, note = _scenario_for(cls, scenario)
    if note:
        add("scenario", True, note)

    missing = [m for m in ("reset", "predict", "update", "estimate", "belief")
               if not callable(getattr(cls, m, None))]
    if not add("interface", not missing, f"missing: {', '.join(missing)}" if missing else
               "reset, predict, update, estimate, belief",
               "implement every method of beacon_sim.filters.base.Filter (subclass FilterBase "
               "to get belief() for free)"):
        return results

    try:
        flt: Filter = cls(_context(scenario, spec))
        reset_filter(flt, scenario)
    except Exception as exc:
        add("constructs", False, f"{type(exc).__name__}: {exc}",
            "the class must take one argument, a FilterContext (call super().__init__(ctx) "
            "when subclassing FilterBase), and reset(initial) must accept a GaussianBelief "
            "or None")
        return results
    add("constructs", True, "built from a FilterContext and reset")

    steps = Simulation(scenario, SEED).run(N_STEPS * scenario.dt)
    n_meas = sum(len(m) for s in steps for m in s.measurements)

    # Shapes, finite values, PSD covariance, wrapped heading, along the run.
    problems: dict[str, str] = {}
    try:
        est0 = flt.estimate()
        p = _estimate_problem(est0)
        if p:
            problems["shapes"] = f"after reset: {p}"
        for k, st in enumerate(steps, 1):
            flt.predict(st.control, st.dt)
            flt.update(st.measurements)
            est = flt.estimate()
            p = _estimate_problem(est)
            if p:
                key = "finite" if "NaN" in p else "shapes"
                problems.setdefault(key, f"step {k}: {p}")
                break
            mean, cov = (np.asarray(a, dtype=float) for a in est)
            scale = max(float(np.max(np.abs(cov))), 1e-12)
            if np.max(np.abs(cov - cov.T)) > 1e-9 * scale:
                problems.setdefault("symmetric", f"step {k}: cov - cov^T up to "
                                    f"{np.max(np.abs(cov - cov.T)):.3g}")
            elif np.min(np.linalg.eigvalsh(cov)) < -1e-9 * scale:
                problems.setdefault("psd", f"step {k}: smallest eigenvalue "
                                    f"{np.min(np.linalg.eigvalsh(cov)):.3g}")
            if not -math.pi <= mean[2] < math.pi:
                problems.setdefault("heading", f"step {k}: theta = {mean[2]!r}")
        flt.belief()
    except Exception as exc:
        add("runs", False, f"{type(exc).__name__}: {exc}",
            "run `beacon-sim run SCENARIO --filter YOURS` to see the traceback; predict and "
            "update must accept the Control and the list of Measurement of every step")
        return results
    add("runs", True, f"{N_STEPS} steps, {n_meas} readings")
    add("shapes", "shapes" not in problems, problems.get("shapes", "mean (3,), cov (3, 3)"),
        "estimate() must return (mean, cov) with mean shape (3,) [x, y, theta] and cov (3, 3)")
    add("finite", "finite" not in problems, problems.get("finite", "no NaN or infinity"),
        "look for a division by a zero range or weight sum, or a covariance that was not "
        "kept positive definite")
    add("symmetric covariance", "symmetric" not in problems,
        problems.get("symmetric", "cov == cov^T"),
        "symmetrise after the update (P = (P + P^T) / 2) or use the Joseph form "
        "(I - KH) P (I - KH)^T + K R K^T")
    add("positive semi-definite covariance", "psd" not in problems,
        problems.get("psd", "no negative eigenvalue"),
        "use the Joseph form for the covariance update; P - K S K^T loses definiteness "
        "through rounding")
    add("heading wrapped", "heading" not in problems, problems.get("heading", "in [-pi, pi)"),
        "wrap the heading after predict and update with beacon_sim.core.angles.wrap, and "
        "wrap every angle residual with angles.diff")

    # Belief type.
    try:
        b = flt.belief()
        ok = isinstance(b, GaussianBelief | ParticleBelief | GridBelief)
        add("belief", ok, type(b).__name__,
            "belief() must return a GaussianBelief, ParticleBelief or GridBelief")
    except Exception as exc:
        add("belief", False, f"{type(exc).__name__}: {exc}", "belief() must not raise")

    # Empty update.
    try:
        before = flt.estimate()
        flt.update([])
        flt.update(())
        after = flt.estimate()
        p = _estimate_problem(after)
        same = p is None and np.allclose(np.asarray(before[0]), np.asarray(after[0]), atol=1e-9)
        add("empty update", p is None, p or ("accepted" + ("" if same else "; the mean moved")),
            "update([]) happens on every tick without readings: return without changing "
            "the belief")
    except Exception as exc:
        add("empty update", False, f"{type(exc).__name__}: {exc}",
            "update([]) happens on every tick without readings: return early when the "
            "list is empty")

    # Determinism and the global RNG.
    try:
        state_np = np.random.get_state(legacy=False)  # noqa: NPY002
        state_py = random.getstate()
        np.random.seed(1)  # noqa: NPY002
        random.seed(1)
        ref_np = np.random.get_state(legacy=False)  # noqa: NPY002
        ref_py = random.getstate()
        _, run1 = _run(cls, scenario, spec, steps, 1)
        now_np = np.random.get_state(legacy=False)  # noqa: NPY002
        drew_np = not _same_np_state(now_np, ref_np)
        drew_py = random.getstate() != ref_py
        _, run2 = _run(cls, scenario, spec, steps, 2)
        np.random.set_state(state_np)  # noqa: NPY002
        random.setstate(state_py)
    except Exception as exc:
        add("deterministic", False, f"{type(exc).__name__}: {exc}", "the filter must run "
            "twice from a fresh FilterContext")
        return results
    diff_at = next((k for k, (a, b) in enumerate(zip(run1, run2, strict=True), 1)
                    if not (np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1]))), None)
    add("deterministic", diff_at is None,
        "same estimates bit for bit with the global RNG seeded 1 and 2" if diff_at is None
        else f"estimates differ from step {diff_at} when only the global np.random seed changes",
        "draw random numbers only from ctx.rng (a numpy Generator), never from np.random.* "
        "or random.*")
    add("no global RNG", not (drew_np or drew_py),
        "the global np.random and random states were left untouched" if not (drew_np or drew_py)
        else "the filter drew from the global " + ("np.random" if drew_np else "random") + " generator",
        "replace np.random.normal(...) / np.random.rand(...) by self.ctx.rng.normal(...) / "
        "self.ctx.rng.random(...) (store ctx.rng in __init__)")
    return results


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
