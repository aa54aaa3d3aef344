"""Monte Carlo runs as tidy tables: one row per run and filter, and one row per run, filter
and tick, in long form so pandas / seaborn take them as they are (``sns.lineplot(ticks,
x="time_s", y="err_pos_m", hue="filter")`` draws the mean and its band over the runs).

A table is a dict ``column name -> 1-D array`` (all the same length), like the run tables
of :mod:`beacon_sim.io.tables`. Every column name carries its unit (``_m``, ``_rad``, ``_s``,
``_m2``, ``_rad2``, ``_us``); NEES has none. Errors are estimate - truth, heading wrapped,
world frame. Each row names its ``scenario``, ``seed`` and ``run`` (0, 1, ...), so tables of
several scenarios or seeds concatenate.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from beacon_sim.core.scenario import Scenario
from beacon_sim.evaluation.montecarlo import RunOutput
from beacon_sim.evaluation.pcrb import pcrb
from beacon_sim.evaluation.summary import Thresholds, model_mask

TICK_COLUMNS = ("scenario", "seed", "run", "filter", "tick", "time_s", "err_x_m", "err_y_m",
                "err_theta_rad", "err_pos_m", "sigma_x_m", "sigma_y_m", "sigma_theta_rad", "nees",
                "pcrb_sigma_x_m", "pcrb_sigma_y_m", "pcrb_sigma_theta_rad", "in_model")
RUN_COLUMNS = ("scenario", "seed", "run", "filter", "ticks", "pos_rmse_m", "heading_rmse_rad",
               "mse_x_m2", "mse_y_m2", "mse_theta_rad2", "anees", "final_err_pos_m", "us_per_step",
               "failed", "failed_tick")


def monte_carlo_tables(scenario: Scenario, runs: list[RunOutput],
                       thresholds: Thresholds | None = None) -> dict[str, dict[str, np.ndarray]]:
    """``{"runs": ..., "ticks": ...}`` of ``runs`` (:func:`.montecarlo.run_monte_carlo`);
    ``thresholds`` as eval's (default :class:`~beacon_sim.evaluation.summary.Thresholds`).

    ``ticks``: one row per run, filter and tick 1..T (filters in order, then runs, then
    ticks): the error [m, m, rad] and position error [m], the filter's sigmas (square roots
    of its covariance's diagonal), NEES, the PCRB's sigmas along that run's true path, and
    ``in_model`` (False in the stretches eval leaves out: after a kidnap, a global start).
    After a filter was switched off its rows are NaN.

    ``runs``: one row per run and filter: RMSEs and MSEs over the ``in_model`` ticks with an
    estimate (as ``eval``'s figures), ANEES over them, the last tick's position error, the
    cost per step [us], why the filter was switched off ("" when it was not) and its first
    tick without an estimate (-1 when it ran to the end).
    """
    thresholds = thresholds or Thresholds()
    names = list(runs[0].filters) if runs else []
    T = runs[0].controls.shape[0] if runs else 0
    truths = np.stack([r.truth for r in runs]) if runs else np.zeros((0, 1, 3))
    kid = np.stack([r.kidnapped for r in runs]) if runs else np.zeros((0, 0), dtype=bool)
    P = pcrb(scenario, truths, np.stack([r.controls for r in runs]), kid) if runs else np.zeros((0, 0, 3, 3))
    keep = model_mask(scenario, kid, thresholds.kidnap_window_s, thresholds.global_start_s) if runs \
        else np.zeros((0, 0), dtype=bool)
    psig = np.sqrt(np.clip(np.einsum("rtii->rti", P), 0.0, None)) if runs else np.zeros((0, 0, 3))
    ticks = np.arange(1, T + 1)
    tick_parts: dict[str, list] = {c: [] for c in TICK_COLUMNS}
    run_rows: dict[str, list] = {c: [] for c in RUN_COLUMNS}
    for name in names:
        for i, r in enumerate(runs):
            fr = r.filters[name]
            err = np.asarray(fr.err, dtype=float).reshape(T, 3)
            with np.errstate(invalid="ignore"):
                sig = np.sqrt(np.asarray(fr.var, dtype=float).reshape(T, 3))
            pos = np.hypot(err[:, 0], err[:, 1])
            cols = {"scenario": np.full(T, scenario.name), "seed": np.full(T, r.seed),
                    "run": np.full(T, r.index), "filter": np.full(T, name), "tick": ticks,
                    "time_s": ticks * scenario.dt,
                    "err_x_m": err[:, 0], "err_y_m": err[:, 1], "err_theta_rad": err[:, 2], "err_pos_m": pos,
                    "sigma_x_m": sig[:, 0], "sigma_y_m": sig[:, 1], "sigma_theta_rad": sig[:, 2],
                    "nees": np.asarray(fr.nees, dtype=float).reshape(T),
                    "pcrb_sigma_x_m": psig[i, :, 0], "pcrb_sigma_y_m": psig[i, :, 1],
                    "pcrb_sigma_theta_rad": psig[i, :, 2], "in_model": keep[i]}
            for c in TICK_COLUMNS:
                tick_parts[c].append(cols[c])
            use = keep[i] & np.isfinite(err).all(axis=1)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                mse = np.mean(err[use] ** 2, axis=0) if use.any() else np.full(3, math.nan)
                anees = float(np.nanmean(cols["nees"][use])) if use.any() else math.nan
            off = np.flatnonzero(~np.isfinite(pos))
            failed_tick = int(ticks[off[0]]) if fr.failed and len(off) else -1
            row = {"scenario": scenario.name, "seed": r.seed, "run": r.index, "filter": name,
                   "ticks": int(fr.steps),
                   "pos_rmse_m": math.sqrt(mse[0] + mse[1]), "heading_rmse_rad": math.sqrt(mse[2]),
                   "mse_x_m2": mse[0], "mse_y_m2": mse[1], "mse_theta_rad2": mse[2], "anees": anees,
                   "final_err_pos_m": float(pos[-1]) if T else math.nan,
                   "us_per_step": fr.step_ns / fr.steps / 1e3 if fr.steps else math.nan,
                   "failed": fr.failed or "", "failed_tick": failed_tick}
            for c in RUN_COLUMNS:
                run_rows[c].append(row[c])
    _str = {"scenario", "filter", "failed"}
    _int = {"seed", "run", "tick", "ticks", "failed_tick"}

    def typed(c: str, v) -> np.ndarray:
        dtype = str if c in _str else int if c in _int else bool if c == "in_model" else float
        return np.asarray(v, dtype=dtype)

    tick_table = {c: typed(c, np.concatenate(v) if v else []) for c, v in tick_parts.items()}
    run_table = {c: typed(c, v) for c, v in run_rows.items()}
    return {"runs": run_table, "ticks": tick_table}
