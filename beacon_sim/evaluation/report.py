"""The evaluation's outputs: the terminal table, ``eval.csv`` (the table), ``eval_runs.csv``
(one row per run and filter), ``eval_recovery.csv`` (one row per kidnap and filter),
``eval.json`` and the PNG plots.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from beacon_sim.core.csv_cells import csv_dict_writer, csv_writer
from beacon_sim.core.files import atomic_write
from beacon_sim.evaluation.intervals import text as interval_text

#: ``eval.csv``'s columns, one row per scenario and filter. Every column that has a unit
#: names it; a field has the same name in every file (``eval_runs.csv``, ``eval_recovery.csv``,
#: :func:`beacon_sim.evaluate`'s tables). A failed filter's accuracy cells are empty, its row
#: says ``failed_runs`` and the first failure (seed, time, reason). Recovery: ``kidnap_runs``
#: kidnaps x runs, ``recovered_runs`` of them recovered, ``recovery_median_s`` the median time
#: to recover over all of them (one that never recovered counting as infinitely late: ``inf``
#: when fewer than half recovered, empty when the scenario has no kidnap); per kidnap in
#: ``eval_recovery.csv``.
COLUMNS = ("scenario", "runs", "steps", "filter", "pos_rmse_m", "heading_rmse_rad", "mse_x_m2",
           "mse_y_m2", "mse_theta_rad2", "anees", "anees_lo", "anees_hi", "anees_verdict", "verdict",
           "nees_share_in_band", "anis", "anis_verdict", "diverged_runs", "kidnap_runs",
           "recovered_runs", "recovery_median_s", "us_per_step", "rmse_over_pcrb",
           "rmse_over_pcrb_lo", "rmse_over_pcrb_hi", "anees_ci_lo", "anees_ci_hi",
           "pcrb_pos_rmse_m", "failed_runs", "first_failure")
#: ``eval_recovery.csv``: one row per scenario, filter and kidnap (``kidnap`` counts from 1),
#: with the median's and the count's 95 % bootstrap intervals over runs.
RECOVERY_COLUMNS = ("scenario", "filter", "kidnap", "runs", "recovered_runs", "recovered_runs_lo",
                    "recovered_runs_hi", "recovery_median_s", "recovery_median_s_lo",
                    "recovery_median_s_hi", "recovery_max_s")


def _num(x, fmt: str) -> str:
    return "-" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, fmt)


def recovery_text(recovery: list[dict]) -> str:
    """``"4.2s 98/100"`` per kidnap (median time of those that recovered), ``-`` if none."""
    if not recovery:
        return "-"
    parts = []
    for r in recovery:
        med = "never" if r["median_s"] is None else f"{r['median_s']:.1f}s"
        parts.append(f"{med} {r['recovered']}/{r['runs']}")
    return "; ".join(parts)


def interval_lines(meta: dict[str, Any]) -> list[str]:
    """One line per scored filter: RMSE/PCRB, ANEES, recovery time and recovered count
    with their 95 % bootstrap intervals over runs, and why RMSE/PCRB is below the bound
    when it is."""
    seeds = f"seeds {meta['seed']}..{meta['seed'] + meta['runs'] - 1}"
    lines = []
    for name, r in meta["filters"].items():
        if r.get("failed_runs") or "intervals" not in r:
            continue
        iv = r["intervals"]
        parts = []
        if r.get("rmse_over_pcrb") is not None:
            parts.append(f"RMSE/PCRB {r['rmse_over_pcrb']:.2f} {interval_text(iv['rmse_over_pcrb'], '.2f')}")
        if r.get("anees") is not None:
            parts.append(f"ANEES {r['anees']:.2f} {interval_text(iv['anees'], '.2f')}")
        for k, rec in enumerate(r.get("recovery", [])):
            med = "never" if rec["median_s"] is None else f"{rec['median_s']:.1f} s"
            med_iv = interval_text(rec.get("median_s_interval"), ".1f")
            count_iv = interval_text(rec.get("recovered_interval"), ".0f")
            parts.append(f"recovery {k + 1} {med} {med_iv} {rec['recovered']}/{rec['runs']} {count_iv}")
        if parts:
            lines.append(f"  {name}: " + ", ".join(p.rstrip() for p in parts))
        if r.get("below_bound_reason"):
            lines.append(f"  {name}: {r['below_bound_reason']}")
    if lines:
        lines.insert(0, f"95 % bootstrap intervals over the {meta['runs']} runs ({seeds}):")
    return lines


def table_lines(meta: dict[str, Any], timing: bool = True) -> list[str]:
    """The terminal table of one scenario. ``timing`` False leaves out us/step (the only
    column that changes from one identical run to the next)."""
    b = meta["pcrb"]
    lines = [f"{meta['scenario']}: {meta['runs']} runs x {meta['steps']} steps "
             f"(dt {meta['dt']:g} s), seeds {meta['seed']}..{meta['seed'] + meta['runs'] - 1}; "
             f"PCRB position {b['pos_rmse_m']:.4f} m, heading {b['heading_rmse_rad']:.4f} rad"]
    lo, hi = next(iter(meta["filters"].values()))["anees_band"] if meta["filters"] else (0, 0)
    width = max([12] + [len(_verdict(r)) + 1 for r in meta["filters"].values()])
    head = (f"{'filter':<16}{'pos RMSE':>9}{'head RMSE':>10}{'MSE x':>9}{'MSE y':>9}"
            f"{'MSE th':>9}{'ANEES':>8} {'verdict':<{width}}{'ANIS':>6}{'div':>5}"
            f"{'RMSE/PCRB':>10}{'us/step' if timing else '':>9}  recovery per kidnap")
    lines.append(head)
    for name, r in meta["filters"].items():
        if r.get("failed_runs"):
            first = r["failures"][0]
            at = "" if first["time_s"] is None else f" at {first['time_s']:.2f} s"
            lines.append(f"{name:<16}FAILED in {r['failed_runs']}/{meta['runs']} runs (no score); "
                         f"first: seed {first['seed']}{at}: {first['reason']}")
            for f in r["failed"][1:3]:
                lines.append(f"    failed: {f}")
            continue
        line = (f"{name:<16}{_num(r['pos_rmse_m'], '.4f'):>9}{_num(r['heading_rmse_rad'], '.4f'):>10}"
                f"{_num(r['mse_x'], '.2e'):>9}{_num(r['mse_y'], '.2e'):>9}"
                f"{_num(r['mse_theta'], '.2e'):>9}{_num(r['anees'], '.2f'):>8} "
                f"{_verdict(r):<{width}}{_num(r['anis'], '.2f'):>6}{r['divergences']:>5}"
                f"{_num(r['rmse_over_pcrb'], '.2f'):>10}"
                f"{_num(r['us_per_step'], '.1f') if timing else '':>9}  {recovery_text(r['recovery'])}")
        lines.append(line)
        for f in r["failed"][:3]:
            lines.append(f"    failed: {f}")
    lines.append(f"ANEES 95 % band for {meta['runs']} runs: [{lo:.2f}, {hi:.2f}] (3 dof); ANIS is "
                 "per degree of freedom (1 for an honest filter); div = runs lost "
                 f"(error > {meta['thresholds']['divergence_m']:g} m at the end); recovery: median "
                 f"time until the error stays < {meta['thresholds']['recovery_m']:g} m; verdict: "
                 "the ANEES word, and how far the error is from the bound when over 1.2x")
    lines += interval_lines(meta)
    return lines


def _verdict(r: dict[str, Any]) -> str:
    """The row's verdict (calibration and accuracy against the bound); older results have
    only the ANEES word."""
    return str(r.get("verdict", r["anees_verdict"]))


def _csv_row(meta: dict[str, Any], name: str, r: dict[str, Any]) -> dict[str, Any]:
    kidnap_runs = sum(k["runs"] for k in r["recovery"])
    row = {
        "scenario": meta["scenario"], "runs": meta["runs"], "steps": meta["steps"], "filter": name,
        "pos_rmse_m": r["pos_rmse_m"], "heading_rmse_rad": r["heading_rmse_rad"],
        "mse_x_m2": r["mse_x"], "mse_y_m2": r["mse_y"], "mse_theta_rad2": r["mse_theta"],
        "anees": r["anees"], "anees_lo": r["anees_band"][0], "anees_hi": r["anees_band"][1],
        "anees_verdict": r["anees_verdict"], "verdict": _verdict(r),
        "nees_share_in_band": r["nees_steps_in_band"],
        "anis": r["anis"], "anis_verdict": r["anis_verdict"], "diverged_runs": r["divergences"],
        "kidnap_runs": kidnap_runs,
        "recovered_runs": sum(k["recovered"] for k in r["recovery"]),
        "recovery_median_s": _pooled_recovery_median(r) if kidnap_runs else None,
        "us_per_step": r["us_per_step"],
        "rmse_over_pcrb": r["rmse_over_pcrb"],
        "rmse_over_pcrb_lo": _end(r, "rmse_over_pcrb", 0), "rmse_over_pcrb_hi": _end(r, "rmse_over_pcrb", 1),
        "anees_ci_lo": _end(r, "anees", 0), "anees_ci_hi": _end(r, "anees", 1),
        "pcrb_pos_rmse_m": meta["pcrb"]["pos_rmse_m"],
        "failed_runs": r.get("failed_runs", 0), "first_failure": r["failed"][0] if r["failed"] else "",
    }
    assert tuple(row) == COLUMNS
    return row


def _pooled_recovery_median(r: dict[str, Any]) -> float:
    """The median recovery time [s] over every kidnap of every run, a run that never
    recovered counting as infinitely late (``inf`` when fewer than half recovered)."""
    times = [math.inf if v is None else v for p in r["per_run"] for v in p["recovery_s"]]
    return float(np.median(np.asarray(times, dtype=float))) if times else math.inf


def _recovery_rows(meta: dict[str, Any], name: str, r: dict[str, Any]) -> list[dict[str, Any]]:
    rows = []
    for k, rec in enumerate(r["recovery"]):
        med_iv = rec.get("median_s_interval") or (None, None)
        count_iv = rec.get("recovered_interval") or (None, None)
        rows.append({"scenario": meta["scenario"], "filter": name, "kidnap": k + 1, "runs": rec["runs"],
                     "recovered_runs": rec["recovered"], "recovered_runs_lo": count_iv[0],
                     "recovered_runs_hi": count_iv[1],
                     "recovery_median_s": math.inf if rec["median_s"] is None else rec["median_s"],
                     "recovery_median_s_lo": med_iv[0], "recovery_median_s_hi": med_iv[1],
                     "recovery_max_s": rec.get("max_s")})
    return rows


def _end(r: dict[str, Any], key: str, i: int) -> float | None:
    iv = (r.get("intervals") or {}).get(key)
    return None if iv is None else iv[i]


def write_outputs(out: Path, results, document: dict[str, Any]) -> list[Path]:
    """``eval.csv``, ``eval_runs.csv``, ``eval.json`` and the plots into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    written = []
    with atomic_write(out / "eval.csv", "w", newline="", what="eval table") as fh:
        w = csv_dict_writer(fh, list(COLUMNS))
        w.writeheader()
        for _, meta, _ in results:
            for name, r in meta["filters"].items():
                w.writerow(_csv_row(meta, name, r))
    written.append(out / "eval.csv")
    with atomic_write(out / "eval_recovery.csv", "w", newline="", what="eval table") as fh:
        w = csv_dict_writer(fh, list(RECOVERY_COLUMNS))
        w.writeheader()
        for _, meta, _ in results:
            for name, r in meta["filters"].items():
                for row in _recovery_rows(meta, name, r):
                    w.writerow(row)
    written.append(out / "eval_recovery.csv")
    kidnaps = max((len(p["recovery_s"]) for _, meta, _ in results for r in meta["filters"].values()
                   for p in r["per_run"]), default=0)
    with atomic_write(out / "eval_runs.csv", "w", newline="", what="eval table") as fh:
        rows = csv_writer(fh)
        rows.writerow(["scenario", "filter", "seed", "pos_rmse_m", "heading_rmse_rad", "anees",
                       "diverged", *[f"recovery_{k + 1}_s" for k in range(kidnaps)], "us_per_step",
                       "failed", "failed_time_s"])
        for _, meta, _ in results:
            for name, r in meta["filters"].items():
                for p in r["per_run"]:
                    rec = [math.inf if v is None else v for v in p["recovery_s"]]
                    rec += [None] * (kidnaps - len(rec))
                    rows.writerow([meta["scenario"], name, p["seed"], p["pos_rmse_m"],
                                   p["heading_rmse_rad"], p["anees"], int(p["diverged"]), *rec,
                                   p["us_per_step"], p["failed"] or "", p.get("failed_time_s")])
    written.append(out / "eval_runs.csv")
    with atomic_write(out / "eval.json", "w", what="eval document") as fh:
        json.dump(document, fh, indent=1, default=float)
    written.append(out / "eval.json")
    from beacon_sim.evaluation import plots

    if not plots.available():
        print(plots.INSTALL_HINT, file=sys.stderr)
        return written
    for sc, meta, curves in results:
        written += plots.plot_all(sc, curves, out, meta["runs"])
    return written
