"""A team's Monte Carlo runs reduced to figures (:func:`evaluate_team`), its terminal table
(:func:`team_table_lines`) and its files (:func:`write_team_outputs`).

Each robot's figures are the single-robot evaluation's (``summary.evaluate`` on that robot's
scenario, its truth and each filter's estimates of it, which also gives the robot's bound
*alone*, from its own beacon readings), the team's the RMSE over all robots and the mean of
their ANEES, and ``rmse_over_pcrb`` divides by the joint bound (``pcrb.pcrb`` over the team).
A filter that failed in any run gets no score (its figures None, its verdicts FAILED).
"""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from beacon_sim.core.csv_cells import csv_dict_writer, csv_writer
from beacon_sim.core.files import atomic_write
from beacon_sim.core.metrics import anees_band
from beacon_sim.core.scenario import TeamScenario
from beacon_sim.evaluation.montecarlo import TeamRunOutput
from beacon_sim.evaluation.pcrb import bound_rmse, pcrb, robot_blocks
from beacon_sim.evaluation.summary import (
    Thresholds,
    evaluate,
    json_float,
    model_mask,
    overall_verdict,
    runs_meta,
)
from beacon_sim.runs.headless import anees_verdict

_f = json_float   # JSON-safe float: None for None, NaN and infinity

#: A robot's figures in a team row (from the single-robot evaluation's row).
ROBOT_KEYS = ("pos_rmse_m", "heading_rmse_rad", "mse_x", "mse_y", "mse_theta", "anees",
              "anees_verdict", "nees_steps_in_band", "divergences")


def evaluate_team(team: TeamScenario, runs: list[TeamRunOutput],
                  thresholds: Thresholds | None = None) -> dict[str, Any]:
    """The figures of every team filter over ``runs``: per robot and for the team, the
    joint PCRB per robot (and each robot's bound alone), failures. JSON-ready."""
    thresholds = thresholds or Thresholds()
    R, N = len(runs), len(team.robots)
    names = list(runs[0].filters)
    truths = np.stack([r.truth for r in runs])          # (R, T + 1, N, 3)
    controls = np.stack([r.controls for r in runs])     # (R, T, N, 2)
    T = controls.shape[1]
    P = pcrb(team, truths, controls)
    robot_names = [r.name for r in team.robots]
    per_robot = []  # each robot's single-robot evaluation (its bound alone inside)
    bounds: dict[str, Any] = {}
    for i, robot in enumerate(team.robots):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            meta, _ = evaluate(robot.scenario, [r.robot(i) for r in runs], thresholds)
        per_robot.append(meta)
        keep = model_mask(robot.scenario, np.stack([r.kidnapped[:, i] for r in runs]),
                          thresholds.kidnap_window_s, thresholds.global_start_s)
        b_pos, b_head = bound_rmse(robot_blocks(P, i)[keep]) if keep.any() else (math.nan, math.nan)
        bounds[robot.name] = {"pos_rmse_m": _f(b_pos), "heading_rmse_rad": _f(b_head),
                              "alone_pos_rmse_m": _f(meta["pcrb"]["pos_rmse_m"]),
                              "alone_heading_rmse_rad": _f(meta["pcrb"]["heading_rmse_rad"])}
    b_team = math.sqrt(np.mean([bounds[n]["pos_rmse_m"] ** 2 for n in robot_names]))
    b_alone = math.sqrt(np.mean([bounds[n]["alone_pos_rmse_m"] ** 2 for n in robot_names]))
    lo, hi = anees_band(R)
    tlo, thi = anees_band(R * N)
    rows: dict[str, Any] = {}
    for name in names:
        robots: dict[str, Any] = {}
        for i, rn in enumerate(robot_names):
            src = per_robot[i]["filters"][name]
            row = {k: src[k] for k in ROBOT_KEYS}
            row["pcrb_pos_rmse_m"] = bounds[rn]["pos_rmse_m"]
            row["rmse_over_pcrb"] = (_f(src["pos_rmse_modelled_m"] / bounds[rn]["pos_rmse_m"])
                                     if src["pos_rmse_modelled_m"] is not None and bounds[rn]["pos_rmse_m"]
                                     else None)
            row["rmse_over_pcrb_alone"] = src["rmse_over_pcrb"]
            robots[rn] = row
        first = per_robot[0]["filters"][name]
        failures = first["failures"]
        per_run = []
        for k, r in enumerate(runs):
            fr = r.filters[name]
            ok = not fr[0].failed
            pos2 = math.nan
            if ok:
                pos2 = float(np.mean([np.mean(f.err[:, 0] ** 2 + f.err[:, 1] ** 2) for f in fr]))
            per_run.append({"seed": r.seed, "team_pos_rmse_m": _f(math.sqrt(pos2)) if ok else None,
                            "robots": {rn: per_robot[i]["filters"][name]["per_run"][k]["pos_rmse_m"]
                                       for i, rn in enumerate(robot_names)},
                            "us_per_step": fr[0].step_ns / 1e3 / max(fr[0].steps, 1),
                            "failed": fr[0].failed,
                            "failed_time_s": first["per_run"][k].get("failed_time_s")})
        team_row: dict[str, Any] = {"pos_rmse_m": None, "heading_rmse_rad": None, "anees": None,
                                    "anees_verdict": "FAILED", "rmse_over_pcrb": None,
                                    "rmse_over_pcrb_alone": None}
        if not failures:
            pos = math.sqrt(np.mean([v["pos_rmse_m"] ** 2 for v in robots.values()]))
            head = math.sqrt(np.mean([v["heading_rmse_rad"] ** 2 for v in robots.values()]))
            anees = float(np.mean([v["anees"] for v in robots.values()]))
            team_row = {"pos_rmse_m": _f(pos), "heading_rmse_rad": _f(head), "anees": _f(anees),
                        "anees_verdict": anees_verdict(anees, tlo, thi),
                        "rmse_over_pcrb": _f(pos / b_team) if b_team > 0 else None,
                        "rmse_over_pcrb_alone": _f(pos / b_alone) if b_alone > 0 else None}
        us = [p["us_per_step"] for p in per_run if not p["failed"]]
        rows[name] = {
            "robots": robots,
            "team": team_row,
            "anees_band": [lo, hi],
            "team_anees_band": [tlo, thi],
            "us_per_step": float(np.mean(us)) if us else None,
            "failed_runs": len(failures),
            "failures": failures,
            "failed": first["failed"],
            "per_run": per_run,
        }
    return {
        **runs_meta(team.name, team.dt, runs, T),
        "team": True,
        "robots": robot_names,
        "pcrb": {"robots": bounds, "team_pos_rmse_m": _f(b_team), "team_alone_pos_rmse_m": _f(b_alone)},
        "filters": rows,
    }


def _num(x, fmt: str) -> str:
    return "-" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, fmt)


def team_table_lines(meta: dict[str, Any], timing: bool = True) -> list[str]:
    """The terminal table of a team evaluation: per filter, a row per robot and the team's."""
    lines = [f"{meta['scenario']} (team of {len(meta['robots'])}): {meta['runs']} runs x "
             f"{meta['steps']} steps (dt {meta['dt']:g} s), seeds "
             f"{meta['seed']}..{meta['seed'] + meta['runs'] - 1}"]
    def verdict(v: dict[str, Any]) -> str:   # the ANEES word and the distance from the bound
        return overall_verdict(v["anees_verdict"], v.get("rmse_over_pcrb"))

    width = max([12] + [len(verdict(v)) + 1 for r in meta["filters"].values() if not r["failed_runs"]
                        for v in (*r["robots"].values(), r["team"])])
    head = (f"{'filter':<16}{'robot':<12}{'pos RMSE':>9}{'head RMSE':>10}{'ANEES':>8} {'verdict':<{width}}"
            f"{'PCRB':>9}{'alone':>8}{'RMSE/PCRB':>10}{'us/step' if timing else '':>9}")
    lines.append(head)
    b = meta["pcrb"]
    for name, r in meta["filters"].items():
        if r["failed_runs"]:
            f = r["failures"][0]
            at = "" if f["time_s"] is None else f" at {f['time_s']:.2f} s"
            lines.append(f"{name:<16}FAILED in {r['failed_runs']}/{meta['runs']} runs (no score); "
                         f"first: seed {f['seed']}{at}: {f['reason']}")
            continue
        for k, (rn, v) in enumerate(r["robots"].items()):
            pb = b["robots"][rn]
            lines.append(f"{name if k == 0 else '':<16}{rn:<12}{_num(v['pos_rmse_m'], '.4f'):>9}"
                         f"{_num(v['heading_rmse_rad'], '.4f'):>10}{_num(v['anees'], '.2f'):>8} "
                         f"{verdict(v):<{width}}{_num(pb['pos_rmse_m'], '.4f'):>9}"
                         f"{_num(pb['alone_pos_rmse_m'], '.3f'):>8}{_num(v['rmse_over_pcrb'], '.2f'):>10}")
        t = r["team"]
        lines.append(f"{'':<16}{'team':<12}{_num(t['pos_rmse_m'], '.4f'):>9}"
                     f"{_num(t['heading_rmse_rad'], '.4f'):>10}{_num(t['anees'], '.2f'):>8} "
                     f"{verdict(t):<{width}}{_num(b['team_pos_rmse_m'], '.4f'):>9}"
                     f"{_num(b['team_alone_pos_rmse_m'], '.3f'):>8}{_num(t['rmse_over_pcrb'], '.2f'):>10}"
                     f"{_num(r['us_per_step'], '.0f') if timing else '':>9}")
    lo, hi = next(iter(meta["filters"].values()))["anees_band"] if meta["filters"] else (0, 0)
    tlo, thi = next(iter(meta["filters"].values()))["team_anees_band"] if meta["filters"] else (0, 0)
    lines.append(f"ANEES 95 % band for {meta['runs']} runs: [{lo:.2f}, {hi:.2f}] per robot, "
                 f"[{tlo:.2f}, {thi:.2f}] for the team (3 dof; it takes the robots' NEES as "
                 "independent, which a cooperative filter's are only roughly). PCRB: the joint "
                 "bound on the position RMSE [m] (robot readings couple the robots); alone: each "
                 "robot's bound from its own beacon readings; RMSE/PCRB against the joint bound")
    return lines


def write_team_outputs(out: Path, metas: list[dict[str, Any]], document: dict[str, Any]) -> list[Path]:
    """``eval.csv`` (a row per filter and robot, and the team's), ``eval_runs.csv`` (a row
    per filter and run) and ``eval.json`` into ``out``. No plots for a team."""
    out.mkdir(parents=True, exist_ok=True)
    cols = ["scenario", "runs", "steps", "filter", "robot", "pos_rmse_m", "heading_rmse_rad", "anees",
            "anees_lo", "anees_hi", "anees_verdict", "pcrb_pos_rmse_m", "pcrb_alone_pos_rmse_m",
            "rmse_over_pcrb", "us_per_step", "failed_runs", "first_failure"]
    with atomic_write(out / "eval.csv", "w", newline="", what="eval table") as fh:
        w = csv_dict_writer(fh, cols)
        w.writeheader()
        for m in metas:
            for name, r in m["filters"].items():
                base = {"scenario": m["scenario"], "runs": m["runs"], "steps": m["steps"], "filter": name,
                        "us_per_step": r["us_per_step"], "failed_runs": r["failed_runs"],
                        "first_failure": r["failed"][0] if r["failed"] else ""}
                for rn, v in [*r["robots"].items(), ("team", r["team"])]:
                    pb = m["pcrb"]["robots"].get(rn)
                    band = r["team_anees_band"] if rn == "team" else r["anees_band"]
                    w.writerow({**base, "robot": rn, "pos_rmse_m": v["pos_rmse_m"],
                                "heading_rmse_rad": v["heading_rmse_rad"], "anees": v["anees"],
                                "anees_lo": band[0], "anees_hi": band[1], "anees_verdict": v["anees_verdict"],
                                "pcrb_pos_rmse_m": pb["pos_rmse_m"] if pb else m["pcrb"]["team_pos_rmse_m"],
                                "pcrb_alone_pos_rmse_m": pb["alone_pos_rmse_m"] if pb
                                else m["pcrb"]["team_alone_pos_rmse_m"],
                                "rmse_over_pcrb": v["rmse_over_pcrb"]})
    with atomic_write(out / "eval_runs.csv", "w", newline="", what="eval table") as fh:
        w2 = csv_writer(fh)
        robots = sorted({rn for m in metas for rn in m["robots"]})
        w2.writerow(["scenario", "filter", "seed", "team_pos_rmse_m", *[f"{rn}_pos_rmse_m" for rn in robots],
                     "us_per_step", "failed", "failed_time_s"])
        for m in metas:
            for name, r in m["filters"].items():
                for p in r["per_run"]:
                    w2.writerow([m["scenario"], name, p["seed"], p["team_pos_rmse_m"],
                                 *[p["robots"].get(rn) for rn in robots], p["us_per_step"],
                                 p["failed"] or "", p["failed_time_s"]])
    with atomic_write(out / "eval.json", "w", what="eval document") as fh:
        json.dump(document, fh, indent=1, default=float)
    return [out / "eval.csv", out / "eval_runs.csv", out / "eval.json"]
