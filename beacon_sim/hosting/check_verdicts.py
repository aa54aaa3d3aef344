"""The conformance checks' verdicts (``beacon-sim check``, hosting/conformance.py runs the
filter): each check judges what the filter returned on its own, so one fault gives one FAIL.

The estimates' form and values (shapes, finite, a finite NEES, symmetric and positive
semi-definite covariance, heading wrapped), construction, the runs, ``belief()``, the map
of a SLAM filter, the empty update, determinism and the global random generators; the words
of each verdict and its advice; the built-in peer whose cost a filter's is set beside.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from beacon_sim.core.metrics import pose_errors
from beacon_sim.core.scenario import Scenario
from beacon_sim.core.sensor_kinds import scan_sensors
from beacon_sim.hosting.check_report import CheckResult, verdict
from beacon_sim.hosting.feed import Fed, ProbeFindings
from beacon_sim.hosting.guard import DIVERGED, MAX_COV, MAX_MEAN, NEES_NOT_FINITE


def estimate_form_problem(est: object) -> str | None:
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
class FedSteps:
    """One pass of a filter over the steps: the estimates of the steps that returned,
    the failure that stopped it (step number from 1, its one line), cost [ns]."""

    estimates: list[object]
    error: tuple[int, str] | None
    step_ns: int


def value_problems(estimates: Sequence[object], truths: np.ndarray | None = None) -> dict[str, str]:
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
        p = estimate_form_problem(est)
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


def loads_failed(exc: Exception) -> CheckResult:
    """"loads" failed: the name is no filter, or its file does not import."""
    return CheckResult("loads", False, str(exc), "check the spelling: a built-in name, "
                       "pkg.mod:Class or path/to/file.py:Class, and that the file imports "
                       "without errors")


def check_constructs(why: str | None) -> CheckResult:
    """Was the filter built from a FilterContext and reset (``why``: why not)?"""
    if why is not None:
        return verdict("constructs", False, why.removeprefix("construction failed: "),
                       "the class must take one argument, a FilterContext (call "
                       "super().__init__(ctx) when subclassing FilterBase), and "
                       "reset(initial) must accept a GaussianBelief or None")
    return verdict("constructs", True, "built from a FilterContext and reset")


def check_runs(run: FedSteps, n_meas: int, note: str = "") -> CheckResult:
    """Did every step (predict, update, estimate) return, within the run's time limit?"""
    if run.error is None:
        return verdict("runs", True, f"{len(run.estimates)} steps, {n_meas} readings{note}")
    return verdict("runs", False, f"step {run.error[0]}: {run.error[1]}", RUNS_ADVICE)


RUNS_ADVICE = ("run `beacon-sim run SCENARIO --filter YOURS` to see the traceback; predict and update "
               "must accept the Control and the list of Measurement of every step, and a run must stay "
               "within its time limit")


def estimate_problems(after_reset: list[object], estimates: Sequence[object],
                      truths: np.ndarray | None = None) -> dict[str, str]:
    """The value problems of the estimate after reset (if any, said to be "after reset") and
    of the steps' estimates (see :func:`value_problems`; ``truths``: the steps' true poses,
    for the NEES); the earlier one of each kind wins."""
    problems = {k: "after reset:" + v.removeprefix("step 1:")
                for k, v in value_problems(after_reset).items()}
    for k, v in value_problems(estimates, truths).items():
        problems.setdefault(k, v)
    return problems


def check_shapes(problems: dict[str, str]) -> CheckResult:
    """Is every estimate a (mean, cov) pair of shapes (3,) and (3, 3)?"""
    return verdict("shapes", "shapes" not in problems,
                   problems.get("shapes", "mean (3,), cov (3, 3)"),
                   "estimate() must return (mean, cov) with mean shape (3,) [x, y, theta] and "
                   "cov (3, 3)")


def check_finite(problems: dict[str, str]) -> CheckResult:
    """Is every estimate free of NaN and infinity, not diverged, and its covariance one that
    leaves room for its error (a finite NEES)?"""
    return verdict("finite", "finite" not in problems,
                   problems.get("finite", "no NaN or infinity, not diverged, a finite NEES"),
                   "look for a division by a zero range or weight sum, a covariance that was not "
                   "kept positive definite, one that grows without bound, or one that rules out "
                   "the error it has (a zero variance)")


def check_covariance_symmetric(problems: dict[str, str]) -> CheckResult:
    """Is every covariance symmetric?"""
    return verdict("symmetric covariance", "symmetric" not in problems,
                   problems.get("symmetric", "cov == cov^T"),
                   "symmetrise after the update (P = (P + P^T) / 2) or use the Joseph form "
                   "(I - KH) P (I - KH)^T + K R K^T")


def check_covariance_psd(problems: dict[str, str]) -> CheckResult:
    """Is every covariance positive semi-definite?"""
    return verdict("positive semi-definite covariance", "psd" not in problems,
                   problems.get("psd", "no negative eigenvalue"),
                   "use the Joseph form for the covariance update; P - K S K^T loses "
                   "definiteness through rounding")


def check_heading_wrapped(problems: dict[str, str]) -> CheckResult:
    """Is every heading in [-pi, pi)?"""
    return verdict("heading wrapped", "heading" not in problems,
                   problems.get("heading", "in [-pi, pi)"),
                   "wrap the heading after predict and update with beacon_sim.core.angles.wrap, "
                   "and wrap every angle residual with angles.diff")


def check_belief(why: str | None) -> CheckResult:
    """Did ``belief()`` (asked at the end of the run) return one of the three belief types
    (``why``: what was wrong; "not asked": the run failed before)?"""
    if why == "not asked":
        return verdict("belief", True, "not judged: the filter failed before (see above)")
    return verdict("belief", why is None, why or "a GaussianBelief, ParticleBelief or GridBelief",
                   "belief() must return a GaussianBelief, ParticleBelief or GridBelief and must "
                   "not raise")


LANDMARKS_ADVICE = ("landmarks() must return LandmarkMap(ids, means, covs): ids None or (M,) ints, "
                    "means (M, 2) [m], covs (M, 2, 2) [m^2] symmetric positive semi-definite "
                    "(filters/base.py, docs/slam.md)")


def check_landmarks(fed: Fed, k: int, note: str) -> CheckResult:
    """Was the SLAM filter's map (slot k of ``fed``, judged on every step as ``grade`` judges
    it) well formed? The first step with a fault, one FAIL naming it."""
    why = fed.failed[k]
    if why is not None and why.startswith("landmarks()"):
        return verdict("landmarks", False, f"step {int(fed.failed_at[k] or 0) + 1}{note}: {why}",
                       LANDMARKS_ADVICE)
    if why is not None and fed.done(k) == 0:
        return verdict("landmarks", False, f"not run{note}: {why}", LANDMARKS_ADVICE)
    n = 0 if fed.maps[k] is None else len(fed.maps[k][1])
    return verdict("landmarks", True, f"ids, means (M, 2), covs (M, 2, 2) finite, symmetric, PSD "
                   f"on every step{note}; up to {n} landmarks")


@dataclass
class EmptyTrial:
    """An update without readings on a fresh filter: the estimates before it (after
    predict) and after it, why the step failed (``Type: message``) and why the estimate
    after it failed, or None."""

    before: object
    after: object
    why: str | None
    why_after: str | None


def check_empty_update(trial: EmptyTrial) -> CheckResult:
    """Is an empty update accepted without spoiling a usable estimate?"""
    if trial.why_after is not None:
        return verdict("empty update", True, "not judged: the filter failed before (see above)")
    if trial.why is not None:
        return verdict("empty update", False, trial.why, "update([]) happens on every tick "
                       "without readings: return early when the list is empty")
    before, after = trial.before, trial.after
    usable_before = estimate_form_problem(before) is None and not value_problems([before])
    spoilt = usable_before and bool(estimate_form_problem(after) or value_problems([after]))
    moved = not spoilt and not same_estimates(before, after)
    return verdict("empty update", not spoilt,
                   "spoils the estimate" if spoilt
                   else ("accepted" + ("; the mean moved" if moved else "")),
                   "update([]) happens on every tick without readings: return without "
                   "changing the belief")


def same_estimates(a: object, b: object) -> bool:
    """Bit-identical estimates (NaN equal to NaN: a NaN is the finite check's business)."""
    try:
        return all(np.array_equal(np.asarray(x, dtype=float), np.asarray(y, dtype=float),
                                  equal_nan=True) for x, y in zip(a, b, strict=True))  # type: ignore[call-overload]
    except (TypeError, ValueError):
        return repr(a) == repr(b)


@dataclass
class RngTrial:
    """The run and its copy fed again in the same batch (``run1``, ``run2``; ``others``: the
    run with its readings drawn again and its copy), and whether the batch drew from the
    global ``np.random`` / ``random`` generators."""

    run1: FedSteps
    run2: FedSteps
    drew_np: bool
    drew_py: bool
    others: tuple[FedSteps, FedSteps] | None = None
    #: The probes' own verdict (:func:`~beacon_sim.hosting.feed.judge_probes`: which tick
    #: was answered, and why each stopped), when there is one: it decides.
    judged: ProbeFindings | None = None


def first_difference(run1: FedSteps, run2: FedSteps) -> int | None:
    at = next((k for k, (a, b) in enumerate(zip(run1.estimates, run2.estimates, strict=False), 1)
               if not same_estimates(a, b)), None)
    if at is None and (run1.error is None) != (run2.error is None):
        at = min(len(run1.estimates), len(run2.estimates)) + 1
    return at


def check_determinism(trial: RngTrial) -> CheckResult:
    """Are the estimates bit-identical when the same run is fed again?"""
    if trial.judged is not None and trial.judged.deterministic is not None:
        diff_at = trial.judged.differs_at if not trial.judged.deterministic else None
    else:
        pairs = [(trial.run1, trial.run2)] + ([trial.others] if trial.others is not None else [])
        diffs = [d for d in (first_difference(a, b) for a, b in pairs) if d is not None]
        diff_at = min(diffs) if diffs else None
    return verdict("deterministic", diff_at is None,
                   "the same run fed again gives the same estimates bit for bit" if diff_at is None
                   else f"estimates differ from step {diff_at} when the same run is fed again",
                   "draw random numbers only from ctx.rng (a numpy Generator), never from "
                   "np.random.* or random.*, and nothing from the clock, object ids or set order")


def check_global_rng(trial: RngTrial) -> CheckResult:
    """Did the filter leave the global np.random and random generators untouched?"""
    drew_np, drew_py = trial.drew_np, trial.drew_py
    return verdict("no global RNG", not (drew_np or drew_py),
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


__all__ = [
    "LANDMARKS_ADVICE", "RUNS_ADVICE", "EmptyTrial", "FedSteps", "RngTrial", "check_belief",
    "check_constructs", "check_covariance_psd", "check_covariance_symmetric", "check_determinism",
    "check_empty_update", "check_finite", "check_global_rng", "check_heading_wrapped",
    "check_landmarks", "check_runs", "check_shapes", "cost_peer", "estimate_form_problem",
    "estimate_problems", "first_difference", "loads_failed", "same_estimates", "value_problems"
]
