"""Association without IDs on simulated worlds: ``lookalike_beacons`` and ``default``
with clutter."""

from __future__ import annotations

import dataclasses

import numpy as np

from beacon_sim.core.scenario import load_scenario

from .common import Check, Context, Figure, mean_interval, rms_interval, with_iv

#: The association figures' filters: (spec, label); ``jcbb`` is the EKF with JCBB.
ASSOCIATION_FILTERS = (("ekf", "ekf (NN)"), ("jcbb=ekf", "ekf (JCBB)"), ("ukf", "ukf (NN)"),
                       ("pf", "pf"), ("histogram", "histogram"))


#: On ``default_unknown`` also the histogram filter with a smaller uniform floor (kidnap prior).
FLOOR_FILTER = ("floor=histogram", "histogram, `floor = 1e-9`")


def association_filters(which: str) -> tuple[tuple[str, str], ...]:
    """The (spec, label) pairs of the association figure on ``which``."""
    return ASSOCIATION_FILTERS + ((FLOOR_FILTER,) if which == "default_unknown" else ())


def default_unknown_ids():
    """``default`` with its sensor's IDs hidden and 0.3 clutter a reading (docs/association.md)."""
    sc = load_scenario("default")

    def hidden(sensors):
        return tuple(dataclasses.replace(s, correspondence="unknown", clutter_rate=0.3) for s in sensors)
    return dataclasses.replace(sc, name="default_unknown", sensors=hidden(sc.sensors),
                               model_sensors=hidden(sc.model_sensors))


def association_seed(args: tuple[str, int]) -> dict:
    """One seed of ``beacon-sim run SCENARIO --associations`` with ``ASSOCIATION_FILTERS``:
    per filter label its :class:`AssociationScore` (the run as it is, then with the IDs told)."""
    from beacon_sim.evaluation.association_metrics import association_scores

    which, seed = args
    sc = default_unknown_ids() if which == "default_unknown" else load_scenario(which)
    specs = [s for s, _ in association_filters(which)]
    scores = association_scores(sc, specs, seed=seed, params={"jcbb": {"association": "jcbb"},
                                                              "floor": {"floor": 1e-9}})
    names = {s.split("=")[0]: label for s, label in association_filters(which)}
    return {names[k]: v for k, v in scores.items()}


def association_figure(ctx: Context, which: str, k: int, intro_text: str) -> Figure:
    """The association table of ``which`` over ``ctx.n(k)`` seeded runs, pooled, with intervals."""
    from concurrent.futures import ProcessPoolExecutor

    from beacon_sim.evaluation.intervals import ratio_of_sums

    seeds = range(ctx.seed, ctx.seed + ctx.n(k))
    with ProcessPoolExecutor(max(1, ctx.jobs)) as pool:
        runs = list(pool.map(association_seed, [(which, s) for s in seeds]))
    checks: dict[str, Check] = {}
    rows = []
    for _, label in association_filters(which):
        sc = [r[label] for r in runs]
        if any(s.failed for s in sc):
            rows.append(f"| {label} | switched off: {next(s.failed for s in sc if s.failed)} | | | | |")
            continue
        right = ratio_of_sums(np.array([s.correct for s in sc]), np.array([s.readings for s in sc]))
        share = sum(s.correct for s in sc) / max(1, sum(s.readings for s in sc))
        rm = [s.rmse for s in sc]
        kn = [s.rmse_known for s in sc]
        cost = [s.rmse_cost for s in sc]
        v_rm, v_kn = float(np.sqrt(np.mean(np.square(rm)))), float(np.sqrt(np.mean(np.square(kn))))
        checks[f"{label} share correct"] = (share, right)
        checks[f"{label} pos RMSE, IDs unknown [m]"] = (v_rm, rms_interval(rm))
        checks[f"{label} pos RMSE, IDs told [m]"] = (v_kn, rms_interval(kn))
        far = sum(r > 1.0 for r in rm)
        rows.append(f"| {label} | {sum(s.readings for s in sc)} | {with_iv(share, right, '.3f')} "
                    f"| {sum(s.false for s in sc)} / {sum(s.missed for s in sc)} "
                    f"| {with_iv(v_rm, rms_interval(rm), '.3f')} | {with_iv(v_kn, rms_interval(kn), '.3f')} "
                    f"| {with_iv(float(np.mean(cost)), mean_interval(cost), '+.3f')} | {far}/{len(sc)} |")
    return Figure([
        f"{intro_text} {len(seeds)} seeded runs, seeds {ctx.seeds(k)}, each run twice: as it is "
        "and with the IDs told and no clutter (the same truth; `evaluation/association_metrics.py`, "
        "the columns of [association.md](association.md#metrics-beacon-sim-run---associations)). "
        "Pooled over the runs; RMSE: the root mean square of the runs' position RMSE; cost: the "
        "mean per run of RMSE with unknown IDs minus RMSE with the IDs told; brackets: 95 % "
        "bootstrap intervals over the runs.", "",
        "| filter | readings | given their beacon (clutter: none) | false / missed | pos RMSE, IDs "
        "unknown [m] | IDs told [m] | cost [m] | runs above 1 m |",
        "|---|---|---|---|---|---|---|---|", *rows, ""], checks)


def fig_lookalike(ctx: Context) -> Figure:
    """Association on ``lookalike_beacons``: ten look-alike doors, the filter told one door off."""
    return association_figure(
        ctx, "lookalike_beacons", 20,
        "`beacon-sim run lookalike_beacons --associations --filter ekf --filter jcbb=ekf --set "
        "jcbb.association=jcbb --filter ukf --filter pf --filter histogram` (30 s; the robot "
        "starts at x = 4 m and is told 6 m, one door off; [association.md](association.md"
        "#the-look-alike-lesson-beacon-sim-play-lookalike_beacons)),")


def fig_unknown_ids(ctx: Context) -> Figure:
    """Association on ``default`` with the IDs hidden and clutter 0.3 a reading."""
    return association_figure(
        ctx, "default_unknown", 10,
        "`default` with its sensor given `correspondence = \"unknown\"` and `clutter_rate = 0.3` "
        "(120 s; the same filters and command as the look-alike table, and `--filter "
        "floor=histogram --set floor.floor=1e-9`: the histogram filter with a smaller uniform "
        "floor),")
