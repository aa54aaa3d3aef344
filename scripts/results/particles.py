"""The particle and grid filters' figures: ``global_kidnap``, one random kidnap, the PF on
``default`` and on ``assignment_kf`` (progressive correction), and the PF at rest."""

from __future__ import annotations

import math

import numpy as np

from beacon_sim.core.scenario import load_scenario
from beacon_sim.evaluation.montecarlo import run_monte_carlo
from beacon_sim.evaluation.summary import Thresholds

from .common import (
    Check,
    Context,
    Figure,
    drawn,
    evaluated,
    md_table,
    mean_interval,
    pos_rmse_interval,
    run,
    table_checks,
    wilson,
    wilson_interval,
    with_iv,
)

STANDSTILL_HEADER = "## The particle filter at rest: a minute's standstill"


STANDSTILL_SCENARIOS = ("default", "two_rooms", "assignment_kf")


def standstill_nees(scenario: str, seed: int, seconds: float, gate: bool) -> float:
    """The particle filter's NEES after ``seconds`` [s] with the robot at rest from t = 0
    (the window's keyboard, never pressed), its standstill gate on or off."""
    from beacon_sim.runs.live import Session

    sc = load_scenario(scenario)
    params = None if gate else {"pf": {"update_min_d": 0.0, "update_min_a": 0.0}}
    s = Session(sc, ["pf"], seed, params)
    for _ in range(round(seconds / sc.dt)):
        s.tick()
    return float(s.status["pf"].nees)


def standstill_section(seeds: range, checks: dict | None = None) -> list[str]:
    """The particle filter's NEES after 60 s at rest, with and without its standstill gate
    (``update_min_d`` / ``update_min_a``), over ``seeds`` on three scenarios; ``checks`` gets
    each scenario's rate of seeds inside the band, gate on, with its Wilson interval."""
    from beacon_sim.core.metrics import anees_band
    from beacon_sim.runs.scene import NEES_BAND

    lo, hi = anees_band(len(seeds), 3)
    md = [STANDSTILL_HEADER, "",
          f"The robot stands still from t = 0 for 60 s (the window's keyboard, never pressed); "
          f"`pf` with its defaults (2,000 particles), seeds {seeds.start}.."
          f"{seeds.stop - 1}. NEES at 60 s: the mean over the seeds against the 95 % "
          f"band for {len(seeds)} values [{lo:.2f}, {hi:.2f}], the median, the "
          f"largest and how many seeds are inside one NEES's 95 % band [{NEES_BAND[0]:.2f}, "
          f"{NEES_BAND[1]:.2f}]. Gate on (the default, `update_min_d` = 0.001 m, `update_min_a` "
          "= 0.001 rad: no weighting until the command has moved or turned that much since the "
          "last update, AMCL's rule) and off (0, 0: every tick's readings weighed on particles "
          "that cannot move).", "",
          "| scenario | gate | mean NEES | median | largest | seeds in band |", "|---|---|---|---|---|---|"]
    for name in STANDSTILL_SCENARIOS:
        for gate in (True, False):
            v = np.array([standstill_nees(name, seed, 60.0, gate) for seed in seeds])
            inside = int(np.count_nonzero((v >= NEES_BAND[0]) & (v <= NEES_BAND[1])))
            if gate and checks is not None:
                checks[f"{name}: seeds with pf's NEES in band at rest"] = (
                    inside / len(v), wilson_interval(inside, len(v)))
            md.append(f"| {name} | {'on' if gate else 'off'} | {v.mean():.3g} | {np.median(v):.3g} | "
                      f"{v.max():.3g} | {inside}/{len(v)} |")
    md += ["", "With the gate, the cloud keeps the spread it had when the robot stopped; a kidnap "
           "while the robot stands still shows once it moves again (AMCL's behaviour too).", ""]
    return md


def fig_global_kidnap(ctx: Context) -> Figure:
    """Global localization and two random kidnaps (``global_kidnap``): pf and histogram."""
    md: list[str] = []
    sc = load_scenario("global_kidnap")
    flt = [f for f in ("pf", "histogram") if f in ctx.have]
    rs, meta, curves = evaluated(ctx, sc, flt, 20)
    md += ["The filters start knowing nothing; range-bearing readings within 3.5 m, each beacon "
           "detected on half of the readings; random kidnaps at 30 s and 60 s "
           "([particle-and-grid.md](particle-and-grid.md"
           "#global_kidnap-global-localization-with-a-short-sighted-sensor)). "
           "The ANEES counts the stretches after each kidnap, where a filter is confidently "
           "wrong until it recovers; RMSE/PCRB is taken where the model holds (15-30 s).", "",
           *md_table(meta), ""]
    md += drawn(ctx, sc, curves, meta, "global_kidnap")
    return Figure(md, table_checks(meta, rs))


def run_rmse(rs, name: str) -> np.ndarray:
    """Each run's position RMSE [m] of filter ``name`` (steps with an estimate)."""
    err = np.stack([r.filters[name].err for r in rs])
    return np.sqrt(np.nanmean(err[..., 0] ** 2 + err[..., 1] ** 2, axis=1))


def fig_pf_default(ctx: Context) -> Figure:
    """The particle filter on ``default`` against the EKF, with augmented MCL's injection as
    shipped and switched off: RMSE/PCRB, the worst run against the EKF, the largest error."""
    sc = load_scenario("default")
    flt = [f for f in ("ekf", "pf", "noinject=pf") if f.split("=")[-1] in ctx.have]
    k = 20
    # a labelled filter is not given the scenario's [filters.pf]: give it them, then the change
    params = {"noinject": {**sc.filter_params.get("pf", {}), "augmented": False}}
    rs, meta, _ = run(sc, flt, ctx.n(k), ctx.jobs, params=params, seed=ctx.seed)
    ekf = run_rmse(rs, "ekf")
    checks: dict[str, Check] = {}
    rows = []
    for f, label in (("ekf", "ekf"), ("pf", "pf (augmented MCL, as shipped)"),
                     ("noinject", "pf, `augmented = false`")):
        if f not in meta["filters"]:
            continue
        r = meta["filters"][f]
        iv = (r.get("intervals") or {}).get("rmse_over_pcrb")
        checks[f"{f} RMSE/PCRB"] = (r["rmse_over_pcrb"], iv)
        per = run_rmse(rs, f)
        ratio = per / ekf
        worst = int(np.argmax(ratio))
        err = np.stack([x.filters[f].err for x in rs])
        peak = float(np.nanmax(np.hypot(err[..., 0], err[..., 1])))
        if f == "ekf":
            against = "- | -"
        else:
            checks[f"{f} mean of per-run RMSE / EKF's"] = (float(ratio.mean()), mean_interval(ratio))
            against = (f"{with_iv(float(ratio.mean()), mean_interval(ratio), '.3f')} "
                       f"| {ratio[worst]:.2f} (seed {rs[worst].seed}: {per[worst]:.3f} m against "
                       f"{ekf[worst]:.3f} m)")
        rows.append(f"| {label} | {with_iv(r['rmse_over_pcrb'], iv, '.2f')} | {against} "
                    f"| {peak:.2f} | {r['anees']:.2f} |")
    return Figure([
        f"`default` as shipped (2,000 particles, the scenario's `temper_ess = 0.25`), {ctx.n(k)} "
        f"runs of {sc.duration:g} s, seeds {ctx.seeds(k)} (`beacon-sim eval default --filter ekf "
        f"--filter pf --runs {ctx.n(k)} --seed {ctx.seed}`; the last row with `--set "
        "pf.augmented=false`). Per run, the PF's position RMSE over the EKF's on the same run; "
        "the largest position error of any step of any run. Brackets: 95 % bootstrap intervals "
        "over the runs. What it shows is discussed in [particle-and-grid.md]"
        "(particle-and-grid.md#pf-monte-carlo-localization-beacon_simfiltersparticlepfpy).", "",
        "| filter | RMSE/PCRB | per-run RMSE / EKF's, mean | worst run / EKF's | largest error [m] | ANEES |",
        "|---|---|---|---|---|---|", *rows, ""], checks)


def fig_pf_tempering(ctx: Context) -> Figure:
    """The particle filter on ``assignment_kf`` with and without progressive correction
    (``temper_ess``): ANEES, its median run, the runs whose NEES passes 100 and 1,000."""
    sc = load_scenario("assignment_kf")
    flt = [f for f in ("ekf", "pf", "untempered=pf") if f.split("=")[-1] in ctx.have]
    k = 30
    params = {"untempered": {**sc.filter_params.get("pf", {}), "temper_ess": 0.0}}
    rs, meta, _ = run(sc, flt, ctx.n(k), ctx.jobs, params=params, seed=ctx.seed)
    for name, r in meta["filters"].items():
        r["pos_rmse_interval"] = pos_rmse_interval(rs, name)
    checks: dict[str, Check] = {}
    rows = []
    for f, label in (("pf", "pf, `temper_ess = 0.25` (as shipped)"), ("untempered", "pf, `temper_ess = 0`"),
                     ("ekf", "ekf")):
        if f not in meta["filters"]:
            continue
        r = meta["filters"][f]
        iv = (r.get("intervals") or {}).get("anees")
        nees = np.stack([x.filters[f].nees for x in rs])
        per_run = np.nanmean(nees, axis=1)
        peak = np.nanmax(nees, axis=1)
        over100, over1000 = int((peak > 100).sum()), int((peak > 1000).sum())
        checks[f"{f} ANEES"] = (r["anees"], iv)
        checks[f"{f} pos RMSE [m]"] = (r["pos_rmse_m"], r.get("pos_rmse_interval"))
        checks[f"{f} runs with a NEES above 100 (of {len(rs)})"] = (
            over100 / len(rs), wilson_interval(over100, len(rs)))
        rows.append(f"| {label} | {with_iv(r['anees'], iv, '.3g')} | {r['anees_verdict']} "
                    f"| {np.median(per_run):.2f} | {over100} | {over1000} "
                    f"| {with_iv(r['pos_rmse_m'], r.get('pos_rmse_interval'), '.3f')} |")
    lo, hi = next(iter(meta["filters"].values()))["anees_band"]
    return Figure([
        f"`assignment_kf` as shipped, {ctx.n(k)} runs x {sc.duration:g} s, seeds {ctx.seeds(k)} "
        f"(`beacon-sim eval assignment_kf --filter ekf --filter pf --runs {ctx.n(k)} --seed "
        f"{ctx.seed}`, the second PF row with `--set pf.temper_ess=0`); 2,000 particles; ANEES "
        f"band [{lo:.2f}, {hi:.2f}]. Per run: the mean NEES (its median over runs) and whether any "
        "step's NEES passes 100 or 1,000. Brackets: 95 % bootstrap intervals over the runs. What "
        "it shows is discussed in [particle-and-grid.md]"
        "(particle-and-grid.md#progressive-correction-on-assignment_kf).", "",
        "| filter | ANEES | verdict | median run's mean NEES | runs with NEES > 100 | > 1,000 "
        "| pos RMSE [m] |",
        "|---|---|---|---|---|---|---|", *rows, ""], checks)


#: ``tests/filters/test_global_kidnap.py``'s trial: localised start, one random kidnap at
#: ``KIDNAP_TRIAL_S`` [s], recovered when the error stays under 0.5 m for 5 s within
#: ``KIDNAP_ALLOWED_S`` [s].
KIDNAP_TRIAL_S = 5.0


KIDNAP_ALLOWED_S = 15.0


#: The trial's filter settings: (filter, parameters over the scenario's, label).
KIDNAP_CASES = (
    ("pf", None, "pf, the scenario's settings (KLD 1,000-10,000, roughening 1)"),
    ("histogram", None, "histogram, defaults"),
    ("pf", {"adaptive": "off", "roughen": 0.0}, "pf, library defaults (2,000 fixed, no roughening)"),
    ("pf", {"adaptive": "off", "roughen": 0.0, "augmented": False},
     "pf, library defaults without augmented MCL"),
)


def kidnap_trial(args: tuple[int, int]) -> float:
    """Recovery time [s] (inf if none) of ``KIDNAP_CASES[case]`` on ``global_kidnap`` with
    one random kidnap, seed ``seed``."""
    from beacon_sim.core.events import Kidnap
    from beacon_sim.core.scenario import InitialBelief
    from beacon_sim.evaluation.metrics import recovery_times
    from beacon_sim.runs.headless import run_headless

    case, seed = args
    name, params, _ = KIDNAP_CASES[case]
    base = load_scenario("global_kidnap")
    sc = base.with_changes(events=(Kidnap(time=KIDNAP_TRIAL_S, random=True),),
                           initial_belief=InitialBelief(mean=base.initial_pose, std=(0.1, 0.1, 0.05)))
    th = Thresholds()
    r = run_headless(sc, [name], seed=seed, duration=KIDNAP_TRIAL_S + KIDNAP_ALLOWED_S + th.recovery_hold_s,
                     params={name: params} if params else None)
    tr = r.runner.tracks[name]
    if tr.failed is not None:
        return math.inf
    err = np.hypot(*(np.array(tr.means)[:, :2] - r.truth[:, :2]).T)
    kidnaps = [i for i, s in enumerate(r.steps) if s.kidnapped]
    times = np.array([s.time for s in r.steps])
    return float(recovery_times(err, times, kidnaps, th.recovery_m, th.recovery_hold_s)[0])


def fig_kidnap_trials(ctx: Context) -> Figure:
    """One random kidnap on ``global_kidnap`` from a localised start: the trials recovered
    within 15 s for the scenario's pf, the grid filter, and the pf without its settings."""
    from concurrent.futures import ProcessPoolExecutor

    n = ctx.n(40)
    seeds = list(range(ctx.seed, ctx.seed + n))
    cases = [i for i, (f, _, _) in enumerate(KIDNAP_CASES) if f in ctx.have]
    with ProcessPoolExecutor(max(1, ctx.jobs)) as pool:
        times = list(pool.map(kidnap_trial, [(c, s) for c in cases for s in seeds]))
    checks: dict[str, Check] = {}
    rows = []
    for j, c in enumerate(cases):
        t = np.array(times[j * n:(j + 1) * n])
        ok = t <= KIDNAP_ALLOWED_S
        k = int(ok.sum())
        label = KIDNAP_CASES[c][2]
        checks[f"{label}: trials recovered (of {n})"] = (k / n, wilson_interval(k, n))
        missed = [str(s) for s, good in zip(seeds, ok, strict=True) if not good]
        rows.append(f"| {label} | {wilson(k, n)} | {np.median(t):.1f} "
                    f"| {'all' if k == 0 else ', '.join(missed) or 'none'} |")
    return Figure([
        f"`global_kidnap` with the trial of `tests/filters/test_global_kidnap.py`: a localised "
        f"start (std 0.1 m, 0.1 m, 0.05 rad), one random kidnap at {KIDNAP_TRIAL_S:g} s; a trial "
        f"*recovers* when the position error falls below 0.5 m within {KIDNAP_ALLOWED_S:g} s and "
        f"stays there 5 s. {n} trials per filter, seeds {ctx.seeds(40)}. Brackets: 95 % Wilson "
        "intervals. What it shows is discussed in [particle-and-grid.md]"
        "(particle-and-grid.md#global_kidnap-global-localization-with-a-short-sighted-sensor).", "",
        "| filter | trials recovered within 15 s | median recovery [s] | trials that did not (seeds) |",
        "|---|---|---|---|", *rows, ""], checks)


def fig_standstill(ctx: Context) -> Figure:
    """The particle filter at rest: NEES after a minute's standstill, gate on and off."""
    checks: dict[str, Check] = {}
    md = standstill_section(range(ctx.seed, ctx.seed + ctx.n(20)), checks)[2:]
    return Figure(md, checks)


#: The global start's horizon [s] (``global_kidnap``'s first kidnap is at 30 s) and the
#: error that counts as found [m].
GLOBAL_START_S = 30.0
GLOBAL_START_FOUND_M = 0.5


def found_time(err: np.ndarray, dt: float) -> float:
    """The time [s] from which the position error ``err`` (T,) stays below
    ``GLOBAL_START_FOUND_M`` to the end, inf if it does not end there."""
    above = np.flatnonzero(~(err < GLOBAL_START_FOUND_M))
    if above.size == 0:
        return 0.0
    return math.inf if above[-1] == err.size - 1 else (above[-1] + 1) * dt


def before_kidnap(r) -> int:
    """The steps of run ``r`` before its first kidnap (all of them without one)."""
    k = np.flatnonzero(np.asarray(r.kidnapped))
    return int(k[0]) if k.size else len(r.kidnapped)


def fig_global_start(ctx: Context) -> Figure:
    """``global_kidnap``'s global start: the time until each filter's error stays below 0.5 m,
    for the PF with and without roughening and the grid filter."""
    sc = load_scenario("global_kidnap")
    flt = [f for f in ("pf", "noroughen=pf", "histogram") if f.split("=")[-1] in ctx.have]
    k = 40
    params = {"noroughen": {**sc.filter_params.get("pf", {}), "roughen": 0.0}}
    rs = run_monte_carlo(sc, flt, ctx.n(k), seed=ctx.seed, duration=GLOBAL_START_S, jobs=ctx.jobs,
                         params=params, progress=True)
    checks: dict[str, Check] = {}
    rows = []
    for f, label in (("pf", "pf, the scenario's settings (KLD, `roughen = 1`)"),
                     ("noroughen", "pf, `roughen = 0`"), ("histogram", "histogram")):
        if f not in rs[0].filters:
            continue
        t = np.array([found_time(np.hypot(*r.filters[f].err[:before_kidnap(r), :2].T), sc.dt) for r in rs])
        n = len(t)
        row = [label]
        for within in (6.0, 15.0):
            kk = int((t <= within).sum())
            checks[f"{f}: runs found within {within:g} s (of {n})"] = (kk / n, wilson_interval(kk, n))
            row.append(wilson(kk, n))
        fin = t[np.isfinite(t)]
        row += [f"{np.median(t):.1f}", f"{fin.max():.1f}" if fin.size else "-"]
        rows.append("| " + " | ".join(row) + " |")
    return Figure([
        f"`global_kidnap` as shipped, the filters started knowing nothing, the first "
        f"{GLOBAL_START_S:g} s up to the first kidnap, {ctx.n(k)} runs, seeds {ctx.seeds(k)}; "
        f"the last row but one with `--set pf.roughen=0`. A run is *found* at the time from which "
        f"the position error stays below {GLOBAL_START_FOUND_M:g} m up to the kidnap. "
        "Brackets: 95 % Wilson intervals. What it shows is discussed in [particle-and-grid.md]"
        "(particle-and-grid.md#global_kidnap-global-localization-with-a-short-sighted-sensor).", "",
        "| filter | found within 6 s | within 15 s | median time [s] | latest of those found [s] |",
        "|---|---|---|---|---|", *rows, ""], checks)
