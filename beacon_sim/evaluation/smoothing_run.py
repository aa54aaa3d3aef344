"""Smoothed against filtered, against the truth and the bounds: the figures ``run --smooth``
and ``eval --smooth`` print (docs/smoothing.md).

For each smoothable filter of a run (``runs/smoothing.py``): position and heading RMSE and
ANEES of the filtered and the smoothed track over ticks 1..T, the filtering bound's RMSE
(``pcrb``) and the smoothing bound's (``smoothing_bound``), and each RMSE over its bound.
Over seeds (:func:`smoothing_monte_carlo`): the same figures pooled over runs, with 95 %
bootstrap intervals over runs (``intervals.ratio_of_sums``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from beacon_sim.core.metrics import anees_band, nees, pose_errors
from beacon_sim.core.scenario import Scenario
from beacon_sim.core.types import Step
from beacon_sim.evaluation import intervals
from beacon_sim.evaluation.smoothing_bound import forward_terms, smoothing_bound
from beacon_sim.hosting.loading import filter_display_name
from beacon_sim.runs.headless import run_headless
from beacon_sim.runs.smoothing import smooth_steps, smoothable

#: Per-run sums kept for the intervals: squared position and heading errors, NEES, and the
#: bounds' traces, filtered ("f") and smoothed ("s").
SUM_KEYS = ("f_pos", "f_head", "f_nees", "s_pos", "s_head", "s_nees", "b_pos", "b_head", "bs_pos", "bs_head")


def run_sums(scenario: Scenario, spec: str, seed: int, steps: Sequence[Step],
             params: dict[str, Any] | None = None) -> dict[str, float]:
    """One run's sums over ticks 1..T (see :data:`SUM_KEYS`) and its tick count ``n``."""
    tr = smooth_steps(scenario, spec, seed, steps, params)
    truths = np.array([scenario.initial_pose] + [st.true_pose for st in steps], dtype=float)
    controls = np.array([(st.control.v, st.control.omega) for st in steps], dtype=float)
    rows = tr.ticks[1:]
    truth = truths[rows]
    P, _, _, _ = forward_terms(scenario, truths[None], controls[None])
    Ps = smoothing_bound(scenario, truths[None], controls[None])
    Pf, Ps = P[0, rows], Ps[0, rows - 1]
    out: dict[str, float] = {"n": float(len(rows))}
    for key, means, covs in (("f", tr.filtered_means[1:], tr.filtered_covs[1:]),
                             ("s", tr.smoothed_means[1:], tr.smoothed_covs[1:])):
        e = pose_errors(means, truth)
        out[f"{key}_pos"] = float(np.sum(e[:, 0] ** 2 + e[:, 1] ** 2))
        out[f"{key}_head"] = float(np.sum(e[:, 2] ** 2))
        with np.errstate(all="ignore"):
            out[f"{key}_nees"] = float(np.sum(nees(e, covs)))
    out["b_pos"] = float(np.sum(Pf[:, 0, 0] + Pf[:, 1, 1]))
    out["b_head"] = float(np.sum(Pf[:, 2, 2]))
    out["bs_pos"] = float(np.sum(Ps[:, 0, 0] + Ps[:, 1, 1]))
    out["bs_head"] = float(np.sum(Ps[:, 2, 2]))
    return out


def figures(sums: Sequence[dict[str, float]], with_intervals: bool = True) -> dict[str, Any]:
    """The pooled figures of one or more runs' :func:`run_sums` (intervals with >= 2 runs)."""
    tot = {k: float(sum(s[k] for s in sums)) for k in (*SUM_KEYS, "n")}
    n = tot["n"]
    out: dict[str, Any] = {"runs": len(sums), "ticks": int(n)}
    for key, label in (("f", "filtered"), ("s", "smoothed")):
        bpos, bhead = ("b_pos", "b_head") if key == "f" else ("bs_pos", "bs_head")
        fig = {"pos_rmse_m": (tot[f"{key}_pos"] / n) ** 0.5,
               "heading_rmse_rad": (tot[f"{key}_head"] / n) ** 0.5,
               "anees": tot[f"{key}_nees"] / n,
               "bound_pos_rmse_m": (tot[bpos] / n) ** 0.5,
               "bound_heading_rmse_rad": (tot[bhead] / n) ** 0.5}
        fig["pos_rmse_over_bound"] = fig["pos_rmse_m"] / fig["bound_pos_rmse_m"]
        if with_intervals and len(sums) >= 2:
            col = {k: np.array([s[k] for s in sums]) for k in (*SUM_KEYS, "n")}
            fig["pos_rmse_m_ci"] = intervals.ratio_of_sums(col[f"{key}_pos"], col["n"], sqrt=True)
            fig["anees_ci"] = intervals.ratio_of_sums(col[f"{key}_nees"], col["n"])
            fig["pos_rmse_over_bound_ci"] = intervals.ratio_of_sums(col[f"{key}_pos"], col[bpos], sqrt=True)
        out[label] = fig
    out["anees_band"] = list(anees_band(max(int(n), 1)))
    return out


def smoothing_monte_carlo(scenario: Scenario, spec: str, seeds: Sequence[int],
                          duration: float | None = None, params: dict[str, Any] | None = None
                          ) -> dict[str, Any]:
    """Filter ``spec`` filtered and smoothed over runs with ``seeds``: :func:`figures`."""
    sums = []
    name = filter_display_name(spec)
    for seed in seeds:
        res = run_headless(scenario, [spec], seed=seed, duration=duration, params={name: params or {}},
                           step_limit_s=None)
        if res.failed(name):
            raise ValueError(f"{name} failed on seed {seed}: {res.failed(name)}")
        sums.append(run_sums(res.scenario, spec, seed, res.steps, params))
    return figures(sums)


def run_figures(scenario: Scenario, specs: Sequence[str], seed: int, steps: Sequence[Step],
                params: dict[str, dict[str, Any]] | None = None) -> dict[str, dict[str, Any]]:
    """Each smoothable filter of one run (by display name): :func:`figures` of that run."""
    out = {}
    for spec in specs:
        if smoothable(spec):
            name = filter_display_name(spec)
            out[name] = figures([run_sums(scenario, spec, seed, steps, (params or {}).get(name))])
    return out


def table_lines(figs: dict[str, dict[str, Any]]) -> list[str]:
    """The text table of :func:`run_figures` / :func:`smoothing_monte_carlo` results."""
    lines = [f"{'smoothing':<12}{'':<10}{'pos RMSE m':>11}{'head RMSE':>11}{'ANEES':>8}"
             f"{'bound m':>10}{'RMSE/bound':>12}  (bound: the filtering PCRB / the smoothing bound)"]
    for name, f in figs.items():
        for label in ("filtered", "smoothed"):
            r = f[label]
            ci = r.get("pos_rmse_over_bound_ci")
            lines.append(f"{name if label == 'filtered' else '':<12}{label:<10}{r['pos_rmse_m']:>11.4f}"
                         f"{r['heading_rmse_rad']:>11.4f}{r['anees']:>8.2f}{r['bound_pos_rmse_m']:>10.4f}"
                         f"{r['pos_rmse_over_bound']:>12.3f}"
                         + (f" {intervals.text(ci, '.3f')}" if ci else ""))
    return lines


__all__ = ["figures", "run_figures", "run_sums", "smoothing_monte_carlo", "table_lines"]
