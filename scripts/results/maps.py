"""The map worlds' figures: seed 004's corridor, global localization in the ``corridor``,
the office (kidnap recovery, the particle-count sweep), the symmetric room, the scan bound
and ``two_rooms``."""

from __future__ import annotations

import math

import numpy as np

from beacon_sim.core.scenario import load_scenario
from beacon_sim.evaluation.intervals import text as interval_text

from .common import (
    Check,
    Context,
    Figure,
    drawn,
    evaluated,
    helper_module,
    md_table,
    rms_interval,
    run,
    table_checks,
    wilson,
    wilson_interval,
    with_iv,
)

CORRIDOR_HEADER = "## [Seed 004](references.md#seed-004): the corridor's discrete Bayes filter"


def fig_corridor(ctx: Context) -> Figure:
    """Seed 004's experiment reproduced with ``filters/grid/corridor.py``: its wall layouts, its
    two figures (four moves and sensings from cell 5 facing east, without and with noise),
    then the filter on the ``corridor`` scenario's laser over seeded runs. Self-contained:
    ``python scripts/make_results.py --only corridor`` regenerates this section alone."""
    from beacon_sim.core.simulation import Simulation
    from beacon_sim.filters.grid.corridor import Corridor
    from beacon_sim.hosting.loading import build_filter

    c = Corridor()
    n_states = c.n_states
    md = ["`filters/grid/corridor.py` (`--filter corridor`) is the seed's filter: 20 states (10 cells x "
          "2 directions: state i < 10 is cell i facing east, 19 - i cell i facing west), a "
          "uniform start, \"forward\" 0.8 one cell / 0.1 two / 0.1 stay (mass leaving the corridor "
          "lost, then normalised), \"turn\" 0.9 to state N - 1 - i, and a sensing of walls left, "
          "right and front weighted 0.6 where it matches the state's layout and 0.2 where not. "
          "Regenerate this section alone with `python scripts/make_results.py --only corridor` "
          "(about a minute).", "",
          "**Wall layouts.** The seed names four (L, LR, LRF, R) but not where its doors are; "
          "ours (the `corridor` scenario) has doors north at cells 2 and 6 and south at cell 4, "
          "which gives exactly those four, with x9 = LRF as in the seed:", "",
          "| state | " + " | ".join(f"x{s}" for s in range(n_states)) + " |",
          "|---|" + "---|" * n_states,
          "| layout | " + " | ".join(c.layout(s) for s in range(n_states)) + " |", ""]

    # -- the seed's figure 1: four forward + sense steps from x5, no noise ---------------
    bel, state = c.uniform(), 5
    rows = []
    for step in range(1, 5):
        bel = c.forward(bel)
        state += 1
        bel = c.sense(bel, c.layout(state))
        top = np.argsort(bel)[::-1][:3]
        rows.append(f"| {step} | x{state} ({c.layout(state)}) | " + ", ".join(
            f"x{s} {bel[s]:.3f}" for s in top) + " |")
    bel9 = float(bel[9])
    md += ["**The seed's figure 1** (four moves forward, a sensing after each, no noise; the seed "
           "does not say where its robot starts: from x5 it ends in x9, the state its text names). "
           "The posterior after each step, its three most likely states:", "",
           "| step | true state (reading) | most likely states |", "|---|---|---|", *rows, "",
           f"The seed reports x9 most likely at \"around 0.38\"; here x9 is most likely at "
           f"**{bel[9]:.3f}** (deterministic, as the seed says). The difference is the door layout "
           "(the seed's is not given): each sensing multiplies by 0.6 or 0.2, so the layouts of the "
           "states a step could confuse set the figure.", ""]

    # -- the seed's figure 2: the same four steps with motion and sensing noise ----------
    rng = np.random.default_rng(ctx.seed)
    trials, correct, x9_best = 2000, 0, 0
    flip = 0.1
    for _ in range(trials):
        bel, state = c.uniform(), 5
        for _ in range(4):
            bel = c.forward(bel)
            u = rng.random()                    # the true move: 0.8 one, 0.1 two, 0.1 stay
            state = min(state + (1 if u < 0.8 else 2 if u < 0.9 else 0), n_states // 2 - 1)
            walls = {ch: ch in c.layout(state) for ch in "LRF"}
            reading = "".join(ch for ch, wall in walls.items() if wall != (rng.random() < flip))
            bel = c.sense(bel, reading)
        correct += int(np.argmax(bel)) == state
        x9_best += state == 9 and int(np.argmax(bel)) == 9
    md += [f"**The seed's figure 2** (the same four steps with noise). The seed gives no noise "
           f"figures; here the true robot moves as the filter's model says (0.8 / 0.1 / 0.1, "
           f"stopping at the end wall) and each of the three wall readings is wrong with "
           f"probability {flip}. Over {trials:,} seeded trials (generator seed {ctx.seed}) the most likely "
           f"state is the true one in **{wilson(correct, trials)}** (95 % Wilson interval); the "
           f"seed's one noisy run had the true state x9 most likely, \"not as certain\" "
           f"(x5, x9, x14 close).", ""]

    # -- on the corridor scenario's laser, seeded runs -----------------------------------
    sc = load_scenario("corridor")
    seeds = list(range(ctx.seed, ctx.seed + ctx.n(20)))
    def settled(marks: list, k: int) -> float:
        """The time of the first sensing from which field ``k`` holds at every later one."""
        last_wrong = max((i for i, m in enumerate(marks) if not m[k]), default=-1)
        return marks[last_wrong + 1][0] if last_wrong + 1 < len(marks) else math.inf

    conv, conv_near, n_sense, n_cell, n_state, n_near = [], [], [], [], [], []
    for seed in seeds:
        sim = Simulation(sc, seed=seed)
        f = build_filter("corridor", sc, seed)
        marks = []   # (time, best cell == true cell, best state == true state, within a cell)
        for _ in range(round(sc.duration / sc.dt)):
            st = sim.step()
            f.predict(st.control, st.dt)
            pending = f._pending_sense
            f.update(st.measurements)
            if not pending or f._pending_sense:
                continue
            truth, best = f.state_of(st.true_pose), int(np.argmax(f.bel))
            cell_t, dir_t = f.corridor.cell_and_heading(truth)
            cell_b, dir_b = f.corridor.cell_and_heading(best)
            marks.append((st.time, cell_b == cell_t, best == truth,
                          dir_b == dir_t and abs(cell_b - cell_t) <= 1))
        ok = [m[1] for m in marks]
        conv.append(settled(marks, 1))
        conv_near.append(settled(marks, 3))
        n_sense.append(len(marks))
        n_cell.append(sum(ok))
        n_state.append(sum(m[2] for m in marks))
        n_near.append(sum(m[3] for m in marks))
    from beacon_sim.evaluation.intervals import median_and_count, ratio_of_sums

    den = np.array(n_sense, dtype=float)

    checks: dict[str, Check] = {}

    def rate(k: list, what: str) -> str:
        iv = ratio_of_sums(np.array(k, float), den)
        checks[f"corridor filter: {what}"] = (sum(k) / den.sum(), iv)
        return f"{sum(k) / den.sum():.2f} {interval_text(iv, '.2f')}"

    def settle_rows(times: list, what: str) -> list[str]:
        t = np.array(times)
        med_iv, count_iv = median_and_count(t)
        med = float(np.median(t))
        checks[f"corridor filter: runs converged {what} (of {len(t)})"] = (
            int(np.isfinite(t).sum()), count_iv)
        return [f"| runs converged {what} (to the end of the run) | {int(np.isfinite(t).sum())}/"
                f"{len(t)} {interval_text(count_iv, '.0f')} |",
                f"| ... convergence time, median [s] | "
                f"{'never' if not math.isfinite(med) else f'{med:.1f}'} {interval_text(med_iv, '.1f')} |",
                "| ... each run [s] | " + ", ".join(
                    "never" if not math.isfinite(x) else f"{x:.0f}" for x in t) + " |"]

    md += [f"**On the `corridor` scenario's laser** (the robot drives east to the end wall, turns, "
           f"drives back; the filter's \"forward\" is every metre driven, its \"turn\" every half turn, "
           f"each followed by a sensing of the next scan: L, R, F where the median of the beams within "
           f"15 degrees of that side is under 0.8 m). Started lost, {len(seeds)} runs x "
           f"{round(sc.duration / sc.dt)} steps, seeds {seeds[0]}..{seeds[-1]}; a sensing is "
           f"*correct* when the most likely state's cell is the robot's; *converged* at the first "
           f"sensing from which every later one is correct. Brackets: 95 % bootstrap intervals over "
           f"the runs.", "",
           "| figure | value |", "|---|---|",
           *settle_rows(conv, "to the true cell"),
           *settle_rows(conv_near, "to within one cell, right direction"),
           f"| sensings per run | {int(den.mean())} |",
           f"| correct cell, share of all sensings | {rate(n_cell, 'correct cell, share of sensings')} |",
           f"| correct cell and direction | {rate(n_state, 'correct cell and direction')} |",
           f"| within one cell, right direction | {rate(n_near, 'within one cell, right direction')} |", "",
           "Compared with the seed: its figure 1 is reproduced to within the door layout (x9 "
           f"most likely, {bel9:.3f} against its \"around 0.38\"). Its figure 2 is one noisy run; "
           "ours is a rate over seeded trials under a stated noise. On the scenario the most "
           f"likely state's cell is the robot's at {sum(n_cell) / den.sum():.0%} of the sensings "
           f"and within one cell, facing its way, at {sum(n_near) / den.sum():.0%}; the misses "
           "are the seed's motion model at work (\"if it fails to move forward ... still 80 % of "
           "the probability ... are convolved to the next state\": a 0.1 / 0.1 spread per metre "
           "that look-alike LR cells do not take back); the metre count falls on the cells' "
           "centres ([maps.md](maps.md#seed-004s-discrete-bayes-filter-corridor)).", ""]
    return Figure(md, checks)


def fig_corridor_mcl(ctx: Context) -> Figure:
    """Global localization in the ``corridor`` scenario: the runs in which mcl and the
    corridor filter, started lost, hold the robot's cell and heading from 60 to 90 s."""
    from beacon_sim.evaluation.found import CORRIDOR_CHECK_S, FOUND_RADIUS_M, found_at

    sc = load_scenario("corridor")
    flt = [f for f in ("mcl", "corridor") if f in ctx.have]
    rs, _, _ = run(sc, flt, ctx.n(40), ctx.jobs, duration=max(CORRIDOR_CHECK_S), seed=ctx.seed)
    checks: dict[str, Check] = {}
    rows = []
    for f in flt:
        found = [found_at(r, f, sc.dt) for r in rs]
        k, n_runs = sum(found), len(found)
        checks[f"{f}: runs in the true cell at 60-90 s (of {n_runs})"] = (
            k / n_runs, wilson_interval(k, n_runs))
        missed = [str(r.seed) for r, ok in zip(rs, found, strict=True) if not ok]
        rows.append(f"| {f} | {wilson(k, n_runs)} | {', '.join(missed) or 'none'} |")
    return Figure([
        "The `corridor` scenario as shipped (ten 1 m cells, doors north at cells 2 and 6 and "
        "south at 4, a 360-degree laser; [maps.md](maps.md)), the filters started lost (a "
        f"global belief), {ctx.n(40)} runs, seeds {ctx.seeds(40)}. A run *finds* the robot when, "
        "at each of 60, 70, 80 and 90 s (by then the robot has driven the corridor's length "
        f"and back), the filter's estimate lies within {FOUND_RADIUS_M:g} m of the robot (in the "
        "1 m cell centred on it) and faces its way (cos of the heading error > 0.9), the "
        "criterion of `tests/filters/test_mcl.py` (`evaluation.found`). Brackets: 95 % Wilson intervals.", "",
        "| filter | runs that found the robot | runs that did not (seeds) |", "|---|---|---|",
        *rows, ""], checks)


def office_seed(seed: int) -> bool:
    """One office kidnap trial (``benchmarks/bench_mcl.py``'s): mcl within 0.5 m at the end."""
    return helper_module("benchmarks", "bench_mcl").recovered(seed)


def fig_office_kidnap(ctx: Context) -> Figure:
    """Kidnap recovery in the ``office``: the share of runs whose mcl estimate ends within
    0.5 m of the truth, 70 s after the kidnap to the corridor's far end."""
    from concurrent.futures import ProcessPoolExecutor

    seeds = list(range(ctx.seed, ctx.seed + ctx.n(40)))
    with ProcessPoolExecutor(max(1, ctx.jobs)) as pool:
        ok = list(pool.map(office_seed, seeds))
    k, n = sum(ok), len(ok)
    missed = [str(s) for s, good in zip(seeds, ok, strict=True) if not good]
    return Figure([
        f"`office` as shipped, mcl with the scenario's parameters, {n} runs, seeds "
        f"{ctx.seeds(40)}: a run *recovers* when mcl's estimate at the end (140 s, 70 s after "
        "the kidnap to the corridor's far end) is within 0.5 m of the robot (`python "
        "benchmarks/bench_mcl.py`'s trial, `recovered`). Brackets: 95 % Wilson interval. What it "
        "shows is discussed in [maps.md](maps.md#speed-and-accuracy-benchmarksbench_mclpy).", "",
        "| filter | runs recovered | runs that did not (seeds) |", "|---|---|---|",
        f"| mcl | {wilson(k, n)} | {', '.join(missed) or 'none'} |", ""],
        {f"mcl: runs recovered after the kidnap (of {n})": (k / n, wilson_interval(k, n))})


#: The office sweep's particle counts and seconds of tracking (before the kidnap at 70 s).
OFFICE_SWEEP_COUNTS = (250, 1000, 4000, 16000)


OFFICE_SWEEP_SECONDS = 60.0


def office_track(args: tuple[int, int]) -> tuple[float, float]:
    """``benchmarks/bench_mcl.py``'s ``track``: mcl with a fixed count in the office, one seed."""
    n, seed = args
    return helper_module("benchmarks", "bench_mcl").track(n, seed, OFFICE_SWEEP_SECONDS)


def fig_office_sweep(ctx: Context) -> Figure:
    """Error and CPU against the particle count (as Beluga's reports show them): mcl tracking
    in the office from the scenario's start, fixed counts, the first 60 s."""
    from concurrent.futures import ProcessPoolExecutor

    n = ctx.n(8)
    seeds = list(range(ctx.seed, ctx.seed + n))
    jobs = [(c, s) for c in OFFICE_SWEEP_COUNTS for s in seeds]
    with ProcessPoolExecutor(max(1, ctx.jobs)) as pool:
        res = list(pool.map(office_track, jobs))
    checks: dict[str, Check] = {}
    rows = []
    for i, c in enumerate(OFFICE_SWEEP_COUNTS):
        rmse = np.array([r[0] for r in res[i * n:(i + 1) * n]])
        cpu = float(np.median([r[1] for r in res[i * n:(i + 1) * n]]))
        iv = rms_interval(rmse)
        total = float(np.sqrt(np.mean(rmse ** 2)))
        checks[f"{c} particles: position RMSE [m]"] = (total, iv)
        rows.append(f"| {c:,} | {with_iv(total, iv, '.3f')} | {np.median(rmse):.3f} | {rmse.max():.3f} "
                    f"| {cpu:.2f} |")
    return Figure([
        f"`office` as shipped, mcl tracking from the scenario's start with a fixed particle count "
        f"(`min_particles` = `max_particles`), the first {OFFICE_SWEEP_SECONDS:g} s (before the "
        f"kidnap), {n} runs per count, seeds {ctx.seeds(8)} (`benchmarks/bench_mcl.py`'s `track`). "
        "Position RMSE over each run; over the runs its RMS with a 95 % bootstrap interval, the "
        "median and the worst run; CPU: the median process time of one predict + update with a "
        "scan (measured on this shared machine, not reproducible). What it shows is discussed "
        "in [maps.md](maps.md#speed-and-accuracy-benchmarksbench_mclpy).", "",
        "| particles | position RMSE, RMS over runs [m] | median run [m] | worst run [m] "
        "| CPU per update [ms] |",
        "|---|---|---|---|---|", *rows, ""], checks)


def symmetric_seed(seed: int) -> dict:
    """One ``symmetric_room`` run as ``scripts/symmetric_room_modes.py`` judges it."""
    return helper_module("scripts", "symmetric_room_modes").one_run((seed, {}))


def fig_symmetric_room(ctx: Context) -> Figure:
    """The symmetric room's two clouds: how often both live until the partition is seen,
    and how often mcl ends on the right one (``scripts/symmetric_room_modes.py``)."""
    from concurrent.futures import ProcessPoolExecutor

    seeds = list(range(ctx.seed, ctx.seed + ctx.n(40)))
    with ProcessPoolExecutor(max(1, ctx.jobs)) as pool:
        res = list(pool.map(symmetric_seed, seeds))
    n = len(res)
    rows, checks = [], {}
    for key, what in (("both", "both clouds live to the partition"), ("right", "ends on the truth")):
        k = sum(r[key] for r in res)
        checks[f"mcl: runs where {what} (of {n})"] = (k / n, wilson_interval(k, n))
        missed = [str(r["seed"]) for r in res if not r[key]]
        rows.append(f"| {what} | {wilson(k, n)} | {', '.join(missed) or 'none'} |")
    broke = [r["broke"] for r in res if r["broke"] is not None]
    return Figure([
        f"`symmetric_room` as shipped (mcl started lost, 50,000 particles at the start, "
        f"systematic and selective resampling), {n} runs of 100 s, seeds {ctx.seeds(40)}, each "
        "judged by `scripts/symmetric_room_modes.py`: *both live* when from 7.5 s until the "
        "first true scan with a beam on the partition (the breaking observation, here at "
        f"{min(broke, default=math.nan):.1f}-{max(broke, default=math.nan):.1f} s) the weight within "
        "0.5 m and 0.5 rad of the truth and of its mirror image are both at least 0.02 at every "
        "0.5 s check; *on the truth* when at the end at least 0.9 of the weight is near the "
        "truth. Brackets: 95 % Wilson intervals. What it shows is discussed in "
        "[maps.md](maps.md#the-shipped-map-scenarios).", "",
        "| what | runs | runs where not (seeds) |", "|---|---|---|", *rows, ""], checks)


#: The map worlds whose bound ``fig_map_bound`` compares mcl with, the runs in each and their length [s].
MAP_BOUND_SCENARIOS = ("office", "corridor", "symmetric_room")


MAP_BOUND_RUNS = 10


MAP_BOUND_SECONDS = 30.0


def fig_map_bound(ctx: Context) -> Figure:
    """mcl against the scan PCRB in the map worlds: ``eval``'s RMSE/PCRB over seeded runs of
    ``MAP_BOUND_SECONDS`` (a global start's first 15 s left out, as ``eval`` does)."""
    checks: dict[str, Check] = {}
    rows = []
    k = MAP_BOUND_RUNS
    for name in MAP_BOUND_SCENARIOS:
        sc = load_scenario(name)
        _, meta, _ = evaluated(ctx, sc, ["mcl"], k, duration=MAP_BOUND_SECONDS)
        r = meta["filters"]["mcl"]
        iv = (r.get("intervals") or {}).get("rmse_over_pcrb")
        checks[f"{name}: mcl RMSE/PCRB"] = (r["rmse_over_pcrb"], iv)
        checks[f"{name}: mcl pos RMSE [m]"] = (r["pos_rmse_m"], r.get("pos_rmse_interval"))
        rows.append(f"| `{name}` | {meta['pcrb']['pos_rmse_m'] * 1e3:.2f} "
                    f"| {with_iv(r['pos_rmse_m'], r.get('pos_rmse_interval'), '.4f')} "
                    f"| {with_iv(r['rmse_over_pcrb'], iv, '.3g')} | {r['divergences']}/{ctx.n(k)} |")
    return Figure([
        f"Each map world as shipped, mcl with the scenario's settings, {ctx.n(k)} runs of "
        f"{MAP_BOUND_SECONDS:g} s in each, seeds {ctx.seeds(k)} "
        "(`beacon-sim eval NAME --filter mcl --duration 30`; the scan's information in the "
        "posterior Cramér-Rao bound, [maps.md](maps.md#the-bound)). The corridor and the "
        "symmetric room start lost: their first 15 s are left out of both figures. Brackets: "
        "95 % bootstrap intervals over the runs.", "",
        "| scenario | PCRB, position [mm] | mcl pos RMSE [m] | mcl RMSE/PCRB | diverged |",
        "|---|---|---|---|---|", *rows, ""], checks)


#: When the ``two_rooms`` robot is in the east room, out of sight of every beacon [s].
TWO_ROOMS_BLIND_S = (15.0, 36.0)


def fig_two_rooms(ctx: Context) -> Figure:
    """``two_rooms``: beacons behind walls; the EKF, the PF and dead reckoning against the
    PCRB while the robot is blind in the east room and after."""
    sc = load_scenario("two_rooms")
    flt = [f for f in ("ekf", "pf", "dead_reckoning") if f in ctx.have]
    rs, meta, curves = evaluated(ctx, sc, flt, 20, duration=40.0)
    t = np.asarray(curves["time"])
    bound = np.asarray(curves["pcrb_pos_t"])
    i0, i1 = (int(np.argmin(np.abs(t - x))) for x in TWO_ROOMS_BLIND_S)
    peak = int(np.argmax(bound))
    md = [f"`two_rooms` as shipped, 40 s (`beacon-sim eval two_rooms --duration 40`). The robot "
          "is in the east room, where the walls hide every beacon but one lining up with the "
          f"doorway, from about 15 s to 36 s: the bound's position RMSE is {100 * bound[i0]:.1f} cm "
          f"at {t[i0]:.0f} s, {100 * bound[peak]:.1f} cm at most ({t[peak]:.1f} s) and "
          f"{100 * bound[min(i1 + 20, len(t) - 1)]:.1f} cm at {t[min(i1 + 20, len(t) - 1)]:.0f} s, "
          "once the beacons are in sight again. What it shows is discussed in "
          "[maps.md](maps.md#beacons-behind-walls).", "", *md_table(meta), ""]
    md += drawn(ctx, sc, curves, meta, "two_rooms")
    return Figure(md, table_checks(meta, rs))


#: The corridor tuning ladder (docs/maps.md): mcl's settings before the shipped ones, each a
#: label and the parameters (the scenario's own are the shipped row of ``corridor_global``).
CORRIDOR_LADDER = (
    ("base", "systematic + selective resampling, 4,000 particles",
     {"max_particles": 4000, "min_particles": 500, "blocked_motion_weight": 1.0}),
    ("blocked", "... + `blocked_motion_weight` 0.1",
     {"max_particles": 4000, "min_particles": 500, "blocked_motion_weight": 0.1}),
    ("floor", "... + `min_particles` 2,000",
     {"max_particles": 4000, "min_particles": 2000, "blocked_motion_weight": 0.1}),
    ("product", '`beam_combination = "product"`, 10,000 particles, blocked 0.1',
     {"max_particles": 10000, "min_particles": 500, "blocked_motion_weight": 0.1,
      "beam_combination": "product"}),
)


def fig_corridor_ladder(ctx: Context) -> Figure:
    """The corridor's mcl tuning steps re-measured on unseen seeds: the runs that find the
    robot (``evaluation.found``) with each setting before the shipped one."""
    from beacon_sim.evaluation.found import CORRIDOR_CHECK_S, found_at

    sc = load_scenario("corridor")
    if "mcl" not in ctx.have:
        return Figure(["(mcl is not installed)", ""])
    shipped = sc.filter_params.get("mcl", {})
    specs = [f"{name}=mcl" for name, _, _ in CORRIDOR_LADDER]
    params = {name: {**shipped, **p} for name, _, p in CORRIDOR_LADDER}
    k = 20
    rs, _, _ = run(sc, specs, ctx.n(k), ctx.jobs, duration=max(CORRIDOR_CHECK_S), params=params,
                   seed=ctx.seed)
    checks: dict[str, Check] = {}
    rows = []
    for name, label, _ in CORRIDOR_LADDER:
        found = [found_at(r, name, sc.dt) for r in rs]
        kk, n = sum(found), len(found)
        checks[f"{name}: runs in the true cell at 60-90 s (of {n})"] = (kk / n, wilson_interval(kk, n))
        missed = [str(r.seed) for r, ok in zip(rs, found, strict=True) if not ok]
        rows.append(f"| {label} | {wilson(kk, n)} | {', '.join(missed) or 'none'} |")
    return Figure([
        f"The `corridor` as shipped, mcl started lost with the settings tried before the shipped "
        f"ones (each the scenario's `[filters.mcl]` with the changes named), {ctx.n(k)} runs, seeds "
        f"{ctx.seeds(k)}, the criterion of [the corridor's global localization]"
        "(#global-localization-in-the-corridor-mcl-and-the-corridor-filter) (the shipped "
        "settings' row is there). Brackets: 95 % Wilson intervals. What it shows is discussed in "
        "[maps.md](maps.md#corridor-global-localization).", "",
        "| mcl in the corridor | runs that found the robot | runs that did not (seeds) |",
        "|---|---|---|", *rows, ""], checks)


#: The symmetric room's settings before the shipped ones: (name, label, mcl parameters over
#: the scenario's).
SYMMETRIC_BEFORE = (
    ("before", "the settings before (20,000 particles, multinomial, no selective resampling)",
     {"max_particles": 20000, "resampler": "multinomial", "selective_resampling": False}),
    ("systematic", "20,000 particles, systematic + selective resampling",
     {"max_particles": 20000}),
)


def symmetric_run(args: tuple[int, dict]) -> dict:
    """One ``symmetric_room`` run with mcl ``params`` over the scenario's, as
    ``scripts/symmetric_room_modes.py`` judges it."""
    return helper_module("scripts", "symmetric_room_modes").one_run(args)


def fig_symmetric_before(ctx: Context) -> Figure:
    """The symmetric room's tuning record re-measured on unseen seeds: the settings before the
    shipped 50,000 particles with systematic and selective resampling."""
    from concurrent.futures import ProcessPoolExecutor

    n = ctx.n(40)
    seeds = list(range(ctx.seed, ctx.seed + n))
    jobs = [(s, p) for _, _, p in SYMMETRIC_BEFORE for s in seeds]
    with ProcessPoolExecutor(max(1, ctx.jobs)) as pool:
        res = list(pool.map(symmetric_run, jobs))
    checks: dict[str, Check] = {}
    rows = []
    for j, (name, label, _) in enumerate(SYMMETRIC_BEFORE):
        part = res[j * n:(j + 1) * n]
        cells = []
        for key, what in (("both", "both clouds live to the partition"), ("right", "ends on the truth")):
            k = sum(r[key] for r in part)
            checks[f"{name}: runs where {what} (of {n})"] = (k / n, wilson_interval(k, n))
            cells.append(wilson(k, n))
        rows.append(f"| {label} | {' | '.join(cells)} |")
    return Figure([
        f"`symmetric_room`, mcl started lost with settings tried before the shipped ones (the "
        f"scenario's `[filters.mcl]` with the changes named), {n} runs of 100 s, seeds "
        f"{ctx.seeds(40)} (the same runs as [the shipped settings' figure]"
        "(#two-clouds-in-the-symmetric_room-mcl)), judged as there. Brackets: 95 % Wilson "
        "intervals. What it shows is discussed in [maps.md](maps.md#the-shipped-map-scenarios).", "",
        "| mcl settings | both clouds live to the partition | ends on the truth |", "|---|---|---|",
        *rows, ""], checks)
