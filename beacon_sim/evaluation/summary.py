"""Monte Carlo runs reduced to the figures of the table and the curves of the plots.

Averages are over runs and steps (a filter's steps after it failed are left out). The
ANEES band is the 95 % chi-square band for the average of ``runs`` NEES values (Bar-Shalom's
N-run test): consecutive steps of one run are strongly correlated, so the band is not
narrowed by the number of steps. The NIS of an honest filter is white in time, so its band
uses every degree of freedom.
"""

from __future__ import annotations

import hashlib
import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from beacon_sim.core.events import Kidnap
from beacon_sim.core.metrics import anees_band
from beacon_sim.core.scenario import Scenario
from beacon_sim.evaluation import intervals
from beacon_sim.evaluation.metrics import diverged, recovery_times
from beacon_sim.evaluation.montecarlo import RunOutput, stack
from beacon_sim.evaluation.pcrb import bound_rmse, pcrb
from beacon_sim.filters.loading import initial_belief


@dataclass(frozen=True)
class Thresholds:
    """recovery_m [m] and recovery_hold_s [s]: a kidnapped filter has recovered at the first
    time its position error falls below ``recovery_m`` and stays below for
    ``recovery_hold_s``. divergence_m [m]: a run diverged when the error stays above this
    over the last 10 % of the run (or the filter failed). kidnap_window_s [s] (default: the
    rest of the run) and global_start_s [s]: the stretches after each kidnap and after a
    global start left out of the bound and of RMSE/PCRB, where the filters' model does not
    hold (a kidnap is in no filter's model; after it a filter carries a confidently wrong
    belief until it recovers, however long that takes)."""

    recovery_m: float = 0.5
    recovery_hold_s: float = 5.0
    divergence_m: float = 1.0
    kidnap_window_s: float = math.inf
    global_start_s: float = 15.0


def model_mask(scenario: Scenario, kidnapped: np.ndarray, kidnap_window_s: float = math.inf,
               global_start_s: float = 15.0) -> np.ndarray:
    """Steps where the filters' model holds, bool (R, T): every step except those less than
    ``kidnap_window_s`` seconds from a kidnap (the kidnap's own step included) and, for a
    scenario whose filters start from a global (uniform) belief, the first
    ``global_start_s`` seconds. ``kidnapped`` is bool (R, T)."""
    kid = np.asarray(kidnapped, dtype=bool)
    R, T = kid.shape
    keep = np.ones((R, T), dtype=bool)

    def steps(s: float) -> int:
        return T if not math.isfinite(s) else math.ceil(s / scenario.dt - 1e-9)

    if initial_belief(scenario) is None:
        keep[:, :steps(global_start_s)] = False
    w = steps(kidnap_window_s)
    for r, k in zip(*np.nonzero(kid), strict=True):
        keep[r, k:k + w] = False
    return keep


def left_out_text(scenario: Scenario, thresholds: Thresholds) -> str:
    """Which steps the bound and RMSE/PCRB leave out, in words."""
    kw = thresholds.kidnap_window_s
    parts = ["everything from the first kidnap on" if not math.isfinite(kw)
             else f"{kw:g} s from each kidnap"]
    if initial_belief(scenario) is None:
        parts.append(f"the first {thresholds.global_start_s:g} s (global start)")
    return " and ".join(parts)


def _verdict(value: float, lo: float, hi: float) -> str:
    if not math.isfinite(value):
        return "failed"
    if value > hi:
        return "optimistic"  # errors larger than the covariance admits
    if value < lo:
        return "pessimistic"
    return "consistent"


#: RMSE/PCRB above which a verdict says how far from the bound the filter is, and above
#: which it says "but": calibration alone does not make a filter good.
NEAR_BOUND = 1.2
FAR_FROM_BOUND = 2.0
#: RMSE/PCRB below which the output names the likely reason (an efficient filter sits at 1).
BELOW_BOUND = 0.95


def overall_verdict(calibration: str, ratio: float | None) -> str:
    """The verdict a reader can take as "good" or not: the ANEES word (``calibration``:
    consistent / optimistic / pessimistic / FAILED) with the accuracy against the bound
    (``ratio``, RMSE/PCRB): ``"consistent"`` only within ``NEAR_BOUND`` of the bound,
    ``"consistent, 1.6x the bound"`` up to ``FAR_FROM_BOUND``, then
    ``"consistent, but 14.2x the bound"``."""
    if calibration == "FAILED" or ratio is None or not math.isfinite(ratio):
        return calibration
    if ratio > FAR_FROM_BOUND:
        return f"{calibration}, but {ratio:.1f}x the bound"
    if ratio > NEAR_BOUND:
        return f"{calibration}, {ratio:.1f}x the bound"
    return calibration


def below_bound_reason(scenario: Scenario, truths: np.ndarray, keep: np.ndarray, b_pos: float,
                       ratio: float | None, interval: list[float | None] | None) -> str | None:
    """Why RMSE/PCRB (``ratio``) is below ``BELOW_BOUND``, in words (None when it is not).

    Checked in turn: the interval over runs reaches 1 (too few runs to tell), the true path
    runs within two bound-sigmas of the world's walls on over 5 % of the scored steps
    (filters that keep their estimate inside the world use information the bound leaves
    out), the scenario kidnaps the robot (the scored steps are the ones around the
    kidnaps). ``truths`` (R, T, 3), or (R, T + 1, 3) with the initial pose first, [m, m,
    rad]; ``keep`` bool (R, T): the scored steps."""
    if ratio is None or not math.isfinite(ratio) or ratio >= BELOW_BOUND:
        return None
    if interval is not None and interval[1] is not None and interval[1] >= 1.0:
        n = truths.shape[0]
        return (f"RMSE/PCRB {ratio:.2f} is below the bound but its 95 % interval over the "
                f"{n} runs reaches 1: Monte Carlo noise (more runs narrow it)")
    xmin, ymin, xmax, ymax = scenario.world.bounds
    if truths.shape[1] == keep.shape[1] + 1:   # the runs' truth holds the initial pose too
        truths = truths[:, 1:]
    x, y = truths[..., 0][keep], truths[..., 1][keep]
    margin = 2.0 * b_pos
    near = (x - xmin < margin) | (xmax - x < margin) | (y - ymin < margin) | (ymax - y < margin)
    if near.size and float(near.mean()) > 0.05:
        return (f"RMSE/PCRB {ratio:.2f}: the robot is within {margin:.2f} m (2 bound sigmas) "
                f"of the world's walls on {100 * float(near.mean()):.0f} % of the scored steps; "
                "a filter that keeps its estimate inside the world uses that, the bound does not")
    if any(isinstance(e, Kidnap) for e in scenario.events):
        return (f"RMSE/PCRB {ratio:.2f}: the scenario kidnaps the robot and the scored steps "
                "are those the kidnap windows leave; the bound is taken along the same steps, "
                "but a filter's error there depends on how it was started")
    return (f"RMSE/PCRB {ratio:.2f}: below the bound with none of the usual reasons (walls, "
            "kidnaps, too few runs); check the filter's noise model against the scenario's")


def _f(x: float) -> float | None:
    """JSON-safe float: None for NaN and infinity."""
    return float(x) if math.isfinite(x) else None


#: The figures of a filter's row that a filter failing in any run does not get (None).
NO_SCORE_KEYS = ("pos_rmse_m", "heading_rmse_rad", "mse_x", "mse_y", "mse_theta", "anees",
                 "nees_steps_in_band", "anis", "pos_rmse_modelled_m", "rmse_over_pcrb")


def withhold_failed(row: dict[str, Any], runs: list[RunOutput], name: str, dt: float) -> None:
    """A failed filter gets no score: set ``row["failed_runs"]`` and ``row["failures"]``
    (seed, ``time_s`` of the failing step [s], reason); when any run failed, the accuracy
    and consistency figures become None and the verdicts "FAILED" (an average over the
    steps before a crash would rank a crashed filter above a working one). Per run, a
    failed run's figures become None too."""
    failures = []
    for r, p in zip(runs, row["per_run"], strict=True):
        fr = r.filters[name]
        p["failed_time_s"] = None
        if not fr.failed:
            continue
        bad = np.flatnonzero(~np.isfinite(fr.err[:, 0]))
        t = float((bad[0] + 1) * dt) if len(bad) else None
        p.update(pos_rmse_m=None, heading_rmse_rad=None, anees=None, failed_time_s=t)
        failures.append({"seed": r.seed, "time_s": t, "reason": fr.failed})
    row["failed_runs"] = len(failures)
    row["failures"] = failures
    row["failed"] = [f"seed {f['seed']}" + ("" if f["time_s"] is None else f" at {f['time_s']:.2f} s")
                     + f": {f['reason']}" for f in failures]
    if failures:
        for key in NO_SCORE_KEYS:
            if key in row:
                row[key] = None
        row["anees_verdict"] = row["anis_verdict"] = "FAILED"
        row["spread"]["pos_rmse_m"] = None
        row["recovery"] = []


def evaluate(scenario: Scenario, runs: list[RunOutput], thresholds: Thresholds = Thresholds()):
    """The figures of every filter over ``runs`` (see :func:`_evaluate`). A filter that failed
    in every run has only NaN rows; their empty means are reported as FAILED, not warned."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", "Mean of empty slice", RuntimeWarning)
        warnings.filterwarnings("ignore", "All-NaN slice encountered", RuntimeWarning)
        warnings.filterwarnings("ignore", "Degrees of freedom <= 0", RuntimeWarning)
        return _evaluate(scenario, runs, thresholds)


def _evaluate(scenario: Scenario, runs: list[RunOutput], thresholds: Thresholds):
    """The table rows (dict per filter), the PCRB and the per-step curves for one scenario."""
    names = list(runs[0].filters)
    R = len(runs)
    T = runs[0].controls.shape[0]
    times = scenario.dt * np.arange(1, T + 1)
    truths = np.stack([r.truth for r in runs])
    kid = np.stack([r.kidnapped for r in runs])
    P = pcrb(scenario, truths, np.stack([r.controls for r in runs]), kid)
    keep = model_mask(scenario, kid, thresholds.kidnap_window_s, thresholds.global_start_s)
    b_pos, b_head = bound_rmse(P[keep]) if keep.any() else (math.nan, math.nan)
    lo, hi = anees_band(R)
    curves: dict[str, Any] = {
        "time": times,
        "pcrb_pos_t": np.sqrt(np.mean(P[..., 0, 0] + P[..., 1, 1], axis=0)),
        "pcrb_sigma_t": np.sqrt(np.mean(np.einsum("rtii->rti", P), axis=0)),
        "truth0": truths[0],
        "kidnap_times": times[kid[0]],
        "nees_band": (lo, hi),
        "filters": {},
    }
    rows: dict[str, dict[str, Any]] = {}
    for name in names:
        err = stack(runs, name, "err")  # (R, T, 3)
        nees = stack(runs, name, "nees")  # (R, T)
        var = stack(runs, name, "var")
        with np.errstate(all="ignore"):
            mse = np.nanmean(err**2, axis=(0, 1))
            pos2 = err[..., 0] ** 2 + err[..., 1] ** 2
            run_rmse = np.sqrt(np.nanmean(pos2, axis=1))
            anees = float(np.nanmean(nees))
            nees_t = np.nanmean(nees, axis=0)
        in_band = float(np.mean((nees_t >= lo) & (nees_t <= hi)))
        nis_sum = sum(r.filters[name].nis_sum for r in runs)
        nis_dof = sum(r.filters[name].nis_dof for r in runs)
        anis = nis_sum / nis_dof if nis_dof else math.nan
        nlo, nhi = anees_band(nis_dof, dof=1) if nis_dof else (math.nan, math.nan)
        n_div = 0
        rec: list[list[float]] = []
        per_run = []
        for r in runs:
            fr = r.filters[name]
            perr = np.sqrt(fr.err[:, 0] ** 2 + fr.err[:, 1] ** 2)
            lost = bool(fr.failed) or diverged(perr, thresholds.divergence_m)
            n_div += lost
            rt = recovery_times(perr, times, np.flatnonzero(r.kidnapped), thresholds.recovery_m,
                                thresholds.recovery_hold_s)
            with np.errstate(all="ignore"):
                per_run.append({
                    "seed": r.seed,
                    "pos_rmse_m": _f(float(np.sqrt(np.nanmean(perr**2)))),
                    "heading_rmse_rad": _f(float(np.sqrt(np.nanmean(fr.err[:, 2] ** 2)))),
                    "anees": _f(float(np.nanmean(fr.nees))),
                    "diverged": lost,
                    "recovery_s": [_f(v) for v in rt],
                    "us_per_step": fr.step_ns / 1e3 / max(fr.steps, 1),
                    "failed": fr.failed,
                })
            for k, v in enumerate(rt):
                while len(rec) <= k:
                    rec.append([])
                rec[k].append(v)
        recovery: list[dict[str, Any]] = []
        for vals in rec:
            finite = [v for v in vals if math.isfinite(v)]
            # Median over all runs, a run that did not recover counting as infinitely late:
            # it does not change when longer runs let more of the late ones recover, and is
            # None (never) when fewer than half recovered.
            med = float(np.median(np.sort(np.asarray(vals, dtype=float)))) if vals else math.inf
            recovery.append({"median_s": _f(med),
                             "max_s": _f(max(finite)) if finite else None,
                             "recovered": len(finite), "runs": len(vals)})
        with np.errstate(all="ignore"):
            bound_r = np.sum(np.where(keep, P[..., 0, 0] + P[..., 1, 1], 0.0), axis=1)
            err_r = np.nansum(np.where(keep, pos2, 0.0), axis=1)
            ratio_iv = intervals.ratio_of_sums(err_r, bound_r, sqrt=True) if keep.any() else None
            anees_iv = intervals.ratio_of_sums(np.nansum(nees, axis=1),
                                               np.isfinite(nees).sum(axis=1))
        for k, vals in enumerate(rec):
            med_iv, count_iv = intervals.median_and_count(np.asarray(vals, dtype=float))
            recovery[k]["median_s_interval"] = med_iv
            recovery[k]["recovered_interval"] = count_iv
        us = [r.filters[name].step_ns / 1e3 / max(r.filters[name].steps, 1) for r in runs]
        failed = [f"seed {r.seed}: {r.filters[name].failed}" for r in runs if r.filters[name].failed]
        pos_rmse = float(np.sqrt(mse[0] + mse[1]))
        with np.errstate(all="ignore"):
            modelled_rmse = float(np.sqrt(np.nanmean(pos2[keep]))) if keep.any() else math.nan
        rows[name] = {
            "pos_rmse_m": _f(pos_rmse),
            "heading_rmse_rad": _f(float(np.sqrt(mse[2]))),
            "mse_x": _f(float(mse[0])),
            "mse_y": _f(float(mse[1])),
            "mse_theta": _f(float(mse[2])),
            "anees": _f(anees),
            "anees_band": [lo, hi],
            "anees_verdict": _verdict(anees, lo, hi),
            "nees_steps_in_band": in_band,
            "anis": _f(anis),
            "anis_band": [_f(nlo), _f(nhi)],
            "anis_verdict": _verdict(anis, nlo, nhi) if nis_dof else "no readings",
            "divergences": int(n_div),
            "recovery": recovery,
            "us_per_step": float(np.mean(us)),
            "pos_rmse_modelled_m": _f(modelled_rmse),
            "rmse_over_pcrb": _f(modelled_rmse / b_pos) if b_pos > 0 else None,
            "intervals": {"rmse_over_pcrb": ratio_iv if b_pos > 0 else None, "anees": anees_iv},
            "spread": {
                "pos_rmse_m": {"mean": _f(float(np.nanmean(run_rmse))),
                               "std": _f(float(np.nanstd(run_rmse))),
                               "min": _f(float(np.nanmin(run_rmse))),
                               "median": _f(float(np.nanmedian(run_rmse))),
                               "max": _f(float(np.nanmax(run_rmse)))},
                "us_per_step": {"min": float(np.min(us)), "max": float(np.max(us))},
            },
            "failed": failed,
            "per_run": per_run,
        }
        withhold_failed(rows[name], runs, name, scenario.dt)
        row = rows[name]
        if row.get("failed_runs"):
            row["intervals"] = {"rmse_over_pcrb": None, "anees": None}
        row["verdict"] = overall_verdict(row["anees_verdict"], row["rmse_over_pcrb"])
        row["below_bound_reason"] = below_bound_reason(
            scenario, truths, keep, b_pos, row["rmse_over_pcrb"], row["intervals"]["rmse_over_pcrb"])
        with np.errstate(all="ignore"):
            curves["filters"][name] = {
                "rmse_t": np.sqrt(np.nanmean(pos2, axis=0)),
                "nees_t": nees_t,
                "err0": err[0],
                "sigma0": np.sqrt(np.clip(var[0], 0.0, None)),
                "means0": runs[0].filters[name].means,
            }
    checksum = hashlib.sha256("".join(r.truth_checksum for r in runs).encode()).hexdigest()[:16]
    meta = {
        "scenario": scenario.name,
        "seed": runs[0].seed,
        "runs": R,
        "steps": T,
        "dt": scenario.dt,
        "truth_checksum": checksum,
        "run_checksums": [r.truth_checksum for r in runs],
        "pcrb": {"pos_rmse_m": b_pos, "heading_rmse_rad": b_head,
                 "steps_used": float(keep.mean()),
                 "left_out": left_out_text(scenario, thresholds) if not keep.all() else "nothing"},
        "thresholds": {"recovery_m": thresholds.recovery_m,
                       "recovery_hold_s": thresholds.recovery_hold_s,
                       "divergence_m": thresholds.divergence_m,
                       "kidnap_window_s": _f(thresholds.kidnap_window_s),
                       "global_start_s": thresholds.global_start_s},
        "filters": rows,
    }
    return meta, curves
