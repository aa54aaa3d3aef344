"""Cooperative localization: ``team_sparse``."""

from __future__ import annotations

import time

from beacon_sim.evaluation.summary import evaluate

from .common import Check, Context, Figure, fmt, pos_rmse_interval, with_iv


def fig_team_sparse(ctx: Context) -> Figure:
    """team_sparse: per robot and for the team, each team filter's RMSE and ANEES against
    the joint PCRB and each robot's bound alone (docs/multi-robot.md)."""
    from beacon_sim.core.scenario import load_team_scenario
    from beacon_sim.evaluation.montecarlo.sweep import run_team_monte_carlo
    from beacon_sim.evaluation.team_summary import evaluate_team

    team = load_team_scenario("team_sparse")
    flt = ["independent", "centralised", "decentralised", "ci", "naive"]   # team filters: always built in
    t0 = time.perf_counter()
    rs = run_team_monte_carlo(team, flt, ctx.n(20), seed=ctx.seed, jobs=ctx.jobs)
    meta = evaluate_team(team, rs)
    names = meta["robots"]
    checks: dict[str, Check] = {}
    rows = []
    for f in flt:
        row = meta["filters"][f]
        cells = []
        for i, rn in enumerate(names):
            one = [r.robot(i) for r in rs]
            m, _ = evaluate(team.robots[i].scenario, one)
            r = m["filters"][f]
            iv_r, iv_a = pos_rmse_interval(one, f), (r.get("intervals") or {}).get("anees")
            checks[f"{f} {rn} pos RMSE [m]"] = (r["pos_rmse_m"], iv_r)
            checks[f"{f} {rn} ANEES"] = (r["anees"], iv_a)
            cells.append(f"{with_iv(r['pos_rmse_m'], iv_r, '.3f')} / {with_iv(r['anees'], iv_a, '.3g')}")
        t = row["team"]
        rows.append(f"| {f} | {' | '.join(cells)} | {fmt(t['pos_rmse_m'])} / {fmt(t['anees'], '.3g')} "
                    f"({t['anees_verdict']}) | {fmt(t['rmse_over_pcrb'], '.2f')} "
                    f"| {fmt(row['us_per_step'], '.0f')} |")
    b = meta["pcrb"]
    rows.append(f"| joint PCRB | {' | '.join(fmt(b['robots'][n]['pos_rmse_m']) for n in names)} "
                f"| {fmt(b['team_pos_rmse_m'])} | | |")
    rows.append(f"| PCRB alone | {' | '.join(fmt(b['robots'][n]['alone_pos_rmse_m']) for n in names)} "
                f"| {fmt(b['team_alone_pos_rmse_m'])} | | |")
    lo, hi = next(iter(meta["filters"].values()))["anees_band"]
    tlo, thi = next(iter(meta["filters"].values()))["team_anees_band"]
    return Figure([
        f"`beacon-sim eval team_sparse --runs {ctx.n(20)} --seed {ctx.seed} "
        + " ".join(f"--filter {f}" for f in flt) +
        f"`: {ctx.n(20)} runs of {team.duration:g} s, seeds {ctx.seeds(20)} "
        f"({time.perf_counter() - t0:.0f} s here). Per robot: position RMSE [m] / ANEES "
        f"(95 % band [{lo:.2f}, {hi:.2f}]), brackets 95 % bootstrap intervals over the runs; the "
        f"team: RMSE over the robots / mean ANEES (band [{tlo:.2f}, {thi:.2f}]) and RMSE / joint "
        "PCRB; µs per tick of the whole team filter (measured, varies with the load). What it "
        "shows is discussed in [multi-robot.md](multi-robot.md#team_sparse).", "",
        f"| filter | {' | '.join(names)} | team | team RMSE/PCRB | µs/tick |",
        "|---|" + "---|" * (len(names) + 3), *rows, ""], checks)
