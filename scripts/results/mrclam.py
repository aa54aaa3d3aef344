"""The real-data figures (no seeds): every MRCLAM robot with the known map, with and
without barcodes, and SLAM without the map."""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np

from .common import Context, Figure, fmt, with_iv

#: The time blocks [s] a MRCLAM run is resampled in for its intervals: the errors of real
#: data persist for tens of seconds (robot 3's NEES stays above the 99 % point for up to
#: 60 s), so single steps are not independent; blocks of this length nearly are.
MRCLAM_BLOCK_S = 30.0


MRCLAM_HEADER = "## [Seed 001](references.md#seed-001): EKF against UKF on MRCLAM (real data)"


def mrclam_intervals(run, name: str) -> dict[str, list | None]:
    """95 % block-bootstrap intervals (``MRCLAM_BLOCK_S`` blocks of the run, drawn with
    replacement) of the position RMSE, the ANEES and the share of steps above the 99 % point."""
    from beacon_sim.core.metrics import chi2_quantile, pose_errors
    from beacon_sim.evaluation.intervals import ratio_of_sums
    from beacon_sim.runs.mrclam import nees_or_inf

    tr = run.tracks[name]
    truth, ok = run.data.truth_at(tr.times)
    t = tr.times[ok]
    e = pose_errors(tr.means[ok], truth[ok])
    v = nees_or_inf(e, tr.covs[ok])
    blk = np.floor((t - t[0]) / MRCLAM_BLOCK_S).astype(int)
    cnt = np.bincount(blk).astype(float)
    keep = cnt > 0
    sums = {k: np.bincount(blk, w)[keep] for k, w in
            (("sq", e[:, 0] ** 2 + e[:, 1] ** 2), ("nees", v), ("above", (v > chi2_quantile(0.99, 3)) * 1.0))}
    return {"rmse": ratio_of_sums(sums["sq"], cnt[keep], sqrt=True),
            "anees": ratio_of_sums(sums["nees"], cnt[keep]),
            "above": ratio_of_sums(sums["above"], cnt[keep])}


def mrclam_folder(given: str | None) -> Path | None:
    """The MRCLAM data set's folder (``--mrclam DIR``, else ``$BEACON_SIM_MRCLAM``), or None
    (said on stderr): its tables are then left out."""
    from beacon_sim.io.mrclam import MrclamError, find_dataset

    try:
        return find_dataset(given)
    except MrclamError as exc:
        print(f"the MRCLAM tables are left out: {exc}", file=sys.stderr)
        return None


def mrclam_section(folder: Path | None, have: set[str]) -> list[str]:
    """The MRCLAM part of results.md: every robot of the data set, leave-one-robot-out."""
    md = [MRCLAM_HEADER, ""]
    from beacon_sim.io.mrclam import load_mrclam
    from beacon_sim.runs.mrclam import run_mrclam

    if folder is None:
        return [*md, "This table is produced by `beacon-sim mrclam DIR --robot 1 --filter ekf --filter ukf "
                     "--headless` on a copy of a UTIAS MRCLAM data set (not shipped with the project); "
                     "point `scripts/make_results.py --mrclam DIR` at one to include it here.", ""]
    lines = ["| robot | filter | MSE x [m²] | MSE y [m²] | MSE θ [rad²] | pos RMSE [m] | ANEES "
             "| NEES above 99 % point | largest jump [m] | µs/step | goal |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    cals = ["| robot | forward command scale | turn command scale | Gaussian filters' variance "
            "inflation | noise from |", "|---|---|---|---|---|"]
    goals: dict[str, list[bool]] = {}
    ranges: dict[str, list] = {}
    margins: list[str] = []
    for robot in (1, 2, 3, 4, 5):
        data = load_mrclam(folder, robot)
        res = run_mrclam(data, [f for f in ("ekf", "ukf", "pf") if f in have], calibration="others")
        c = res.calibration
        print(f"MRCLAM robot {robot}: " + ", ".join(
            f"{f} {r.get('pos_rmse_m')} {r.get('anees')} {r.get('nees_above_99')} {r.get('largest_jump_m')}"
            for f, r in res.evaluate().items()), file=sys.stderr, flush=True)
        cals.append(f"| {robot} | {c.v_scale:.3f} | {c.omega_scale:.3f} | {c.inflation:.2f} | "
                    f"robots {', '.join(str(o) for o in (1, 2, 3, 4, 5) if o != robot)} |")
        for f, r in res.evaluate().items():
            if r.get("mse_x") is None:
                continue
            iv = mrclam_intervals(res, f)
            ranges.setdefault(f, []).append((r["pos_rmse_m"], r.get("anees")))
            jump, above = r["largest_jump_m"], r["nees_above_99"]
            met = (r["pos_rmse_m"] <= 0.26 and 1.5 <= r["anees"] <= 6 and above <= 0.05
                   and (f != "pf" or jump <= 1.0))
            goals.setdefault(f, []).append(met)
            reach = [what for what, bad in (
                ("RMSE", iv["rmse"] and iv["rmse"][1] is not None and iv["rmse"][1] > 0.26),
                ("ANEES", iv["anees"] and ((iv["anees"][0] or 0) < 1.5 or (iv["anees"][1] or 0) > 6)),
                ("share above the 99 % point", iv["above"] and (iv["above"][1] or 0) > 0.05)) if bad]
            if reach:
                margins.append(f"robot {robot} {f} ({', '.join(reach)})")
            pct = [None if x is None else 100 * x for x in (iv["above"] or [None, None])]
            lines.append(f"| {robot} | {f} | {r['mse_x']:.4f} | {r['mse_y']:.4f} | {r['mse_theta']:.4f} "
                         f"| {with_iv(r['pos_rmse_m'], iv['rmse'], '.3f')} "
                         f"| {with_iv(r.get('anees'), iv['anees'], '.2f')} "
                         f"| {with_iv(100 * above, pct if iv['above'] else None, '.1f')} % | {jump:.2f} "
                         f"| {fmt(r.get('us_per_step'), '.1f')} | {'met' if met else 'NOT met'} |")
    lines += ["| paper (Table I) | EKF | 1.7875 | 1.889 | 7.7997 | | | | | | |",
              "| paper (Table II) | UKF | 0.0119 | 0.0078 | 0.0571 | | | | | | |"]
    return [
        *md,
        f"{folder.name}, all five robots, whole runs (760-890 s with ground truth each), one setting "
        "for every robot. Regenerate this section alone with `python scripts/make_results.py "
        "--only mrclam` (`--mrclam DIR` for another data set; a few minutes a robot on 2 shared "
        "cores: each robot's calibration runs the EKF on the four others).", "",
        "The noise is calibrated **leave-one-robot-out**: each robot's filters are told what the "
        "data set's four other robots measured, never the ground truth of the run they are scored on "
        "(`beacon-sim mrclam DIR --robot N`, `--calibration others`, the default; `pooled` without "
        "the inflation; `self` fits it on the scored run, labelled as such). From the other robots: "
        "the noise (10 s window residuals, [replay.md](replay.md#mrclam-real-robot-data)), the command "
        "scales (the robots drive 2-8 % less than their odometry commands say) and, for the EKF and UKF, a "
        "variance inflation: the 99 % point of the EKF's NEES on the held-out robots (each "
        "calibrated on the other held-out ones) over the chi-square 99 % point. The particle filter "
        "is told the uninflated noise and weighs readings with the outlier mixture.", "",
        *cals, "",
        "Brackets: 95 % block-bootstrap intervals over the run's "
        f"{MRCLAM_BLOCK_S:g} s blocks (the errors of real data persist for tens of seconds, so "
        "single steps are not independent).", "",
        *lines, "",
        "Goal for every robot: RMSE <= 0.26 m, ANEES 1.5-6, at most 5 % of steps above "
        "the chi-square 99 % point, no particle-filter jump over 1 m. Met: " + "; ".join(
            f"{f} {sum(v)}/{len(v)} robots" for f, v in goals.items()) + ". Ranges over the robots: "
        + "; ".join(f"{f} position RMSE {min(v[0] for v in vals):.3f}-{max(v[0] for v in vals):.3f} m, "
                    f"ANEES {fmt(min(v[1] for v in vals), '.2f')}-{fmt(max(v[1] for v in vals), '.2f')}"
                    for f, vals in ranges.items()) + " (3 for an honest filter). Where a 95 % interval "
        "reaches past a goal's bound, the goal holds on this run but not with that confidence: "
        + ("; ".join(margins) if margins else "none") + ".", "",
        "How this differs from the paper: the paper's EKF fails (MSE θ 7.8 rad², i.e. errors near π) "
        "while its UKF works; here EKF and UKF reach nearly the same error. A heading MSE of 7.8 rad² "
        "is what an unwrapped bearing innovation produces: when the predicted bearing and the reading "
        "straddle ±π the residual is off by 2π and the update throws the heading away. Our filters "
        "wrap every angle difference ([filters.md](filters.md)), and the UKF's sigma-point residuals "
        "are wrapped the same way, so the two agree; both are limited by this data's noisy odometry "
        "and long gaps without a landmark (robot 4: 78 s without one, 0.75 m of drift). The paper "
        "does not say which robot or data set its tables use.", ""]


def anees_cell(value, iv) -> str:
    """The pose ANEES with its interval; an infinite one (a singular covariance) said so."""
    if value is not None and not math.isfinite(value):
        return "inf (singular covariance)"
    return with_iv(value, iv, ".3g")


ASSOCIATION_HEADER = "## Association on MRCLAM: every robot with and without its barcodes"


#: The association table's filters: (label, filter spec, parameters).
MRCLAM_ASSOCIATION_FILTERS = (("ekf (NN)", "ekf", {}),
                              ("ekf (JCBB)", "jcbb=ekf", {"jcbb": {"association": "jcbb"}}),
                              ("ukf (NN)", "ukf", {}), ("pf (ML per particle)", "pf", {}))


def association_section(folder: Path | None) -> list[str]:
    """The known-map filters on every MRCLAM robot, whole runs, told the barcodes and not
    (``--unknown-ids``): RMSE and ANEES both ways, and how many readings each associated with
    the landmark its barcode names; 95 % block-bootstrap intervals over the run's 30 s blocks."""
    md = [ASSOCIATION_HEADER, ""]
    if folder is None:
        return [*md, "Needs a copy of a UTIAS MRCLAM data set (`--mrclam DIR`).", ""]
    from beacon_sim.evaluation.intervals import ratio_of_sums
    from beacon_sim.io.mrclam import load_mrclam
    from beacon_sim.runs.mrclam import run_mrclam

    specs = [spec for _, spec, _ in MRCLAM_ASSOCIATION_FILTERS]
    params: dict = {}
    for _, _, p in MRCLAM_ASSOCIATION_FILTERS:
        params.update(p)
    lines = ["| robot | filter | pos RMSE with IDs [m] | without IDs [m] | ANEES with IDs | without IDs "
             "| readings given the barcoded landmark | false | missed |",
             "|---|---|---|---|---|---|---|---|---|"]
    per_filter: dict[str, list[tuple[float, float, float]]] = {}
    for robot in (1, 2, 3, 4, 5):
        data = load_mrclam(folder, robot)
        runs = {ids: run_mrclam(data, specs, params=params, calibration="others", unknown_ids=not ids)
                for ids in (True, False)}
        evals = {ids: run.evaluate() for ids, run in runs.items()}
        for label, spec, _ in MRCLAM_ASSOCIATION_FILTERS:
            name = spec.split("=")[0]
            a, b = evals[True].get(name, {}), evals[False].get(name, {})
            if a.get("pos_rmse_m") is None or b.get("pos_rmse_m") is None:
                lines.append(f"| {robot} | {label} | failed | | | | | | |")
                continue
            ia, ib = mrclam_intervals(runs[True], name), mrclam_intervals(runs[False], name)
            count = runs[False].associations.get(name)
            share = "-"
            false = missed = "-"
            frac = math.nan
            if count is not None and count.readings:
                hits, rows = count.block_sums(MRCLAM_BLOCK_S)
                iv = ratio_of_sums(hits, rows)
                frac = count.fraction_correct
                pct = None if iv is None else [None if x is None else 100 * x for x in iv]
                share = f"{count.correct} / {count.readings} = {with_iv(100 * frac, pct, '.1f')} %"
                false, missed = str(count.false), str(count.missed)
            per_filter.setdefault(label, []).append((a["pos_rmse_m"], b["pos_rmse_m"], frac))
            print(f"association robot {robot} {label}: {a['pos_rmse_m']:.3f} -> {b['pos_rmse_m']:.3f} m, "
                  f"{share}", file=sys.stderr, flush=True)
            lines.append(f"| {robot} | {label} | {with_iv(a['pos_rmse_m'], ia['rmse'], '.3f')} "
                         f"| {with_iv(b['pos_rmse_m'], ib['rmse'], '.3f')} "
                         f"| {with_iv(a.get('anees'), ia['anees'], '.2f')} "
                         f"| {with_iv(b.get('anees'), ib['anees'], '.2f')} | {share} | {false} | {missed} |")
    summary = ["| filter | pos RMSE with IDs, over robots [m] | without IDs [m] | RMSE without / with, "
               "median over robots | readings given the barcoded landmark, over robots |",
               "|---|---|---|---|---|"]
    for label, rows in per_filter.items():
        w, wo, fr = (np.array(c, dtype=float) for c in zip(*rows, strict=True))
        summary.append(f"| {label} | {w.min():.3f}-{w.max():.3f} | {wo.min():.3f}-{wo.max():.3f} "
                       f"| {np.median(wo / w):.2f} ({(wo / w).min():.2f}-{(wo / w).max():.2f}) "
                       f"| {100 * np.nanmin(fr):.1f}-{100 * np.nanmax(fr):.1f} % |")
    return [
        *md,
        f"{folder.name}, all five robots, whole runs. `beacon-sim mrclam DIR --robot N --headless "
        "--filter ekf --filter jcbb=ekf --set jcbb.association=jcbb --filter ukf --filter pf` and the "
        "same with `--unknown-ids`, which hides every reading's barcode from the filters (they "
        "associate each reading with the 15 surveyed landmarks themselves: nearest neighbour, JCBB, "
        "or per particle) and keeps it only to score them "
        "([association.md](association.md#real-data-beacon-sim-mrclam-dir---robot-n---unknown-ids)). "
        "The noise is the leave-one-robot-out calibration of the table above, the same both ways. "
        "Brackets: 95 % block-bootstrap intervals over the run's 30 s blocks. Regenerate with "
        "`python scripts/make_results.py --only association`.", "",
        *lines, "", "Over the five robots:", "", *summary, ""]


SLAM_HEADER = "## SLAM on MRCLAM: EKF-SLAM and FastSLAM 2.0 without the map"


#: The filters of the SLAM table: the two SLAM filters (no map), the EKF given the map, and
#: odometry alone (the floor a SLAM filter must beat to have used its readings at all).
SLAM_FILTERS = ("ekf_slam", "fastslam", "ekf", "dead_reckoning")


def slam_section(folder: Path | None, have: set[str]) -> list[str]:
    """The SLAM-on-MRCLAM part of results.md: every robot of the data set, whole runs, the
    SLAM filters not given the landmark map, the known-map EKF on the same run; the noise
    leave-one-robot-out as in the MRCLAM table (never fitted on the scored robot)."""
    from beacon_sim.evaluation.intervals import ratio_of_sums
    from beacon_sim.evaluation.slam_run import GOSPA_CUTOFF_M, mrclam_slam_figures
    from beacon_sim.io.mrclam import load_mrclam
    from beacon_sim.runs.mrclam import calibration_for, run_mrclam

    md = [SLAM_HEADER, ""]
    if folder is None:
        return [*md, "This table is produced by `beacon-sim mrclam DIR --robot N --slam --graph "
                     "--headless` on a copy of a UTIAS MRCLAM data set (not shipped with the project); point "
                     "`scripts/make_results.py --mrclam DIR` at one to include it here.", ""]
    flt = [f for f in SLAM_FILTERS if f in have]
    blind = [f for f in flt if f in ("ekf_slam", "fastslam")]

    def map_cell(f: str, given: bool) -> str:
        return "not used" if f == "dead_reckoning" else "given" if given else "none"

    lines = ["| robot | filter | map | IDs | pos RMSE [m] | pose ANEES | map GOSPA [m] | landmarks "
             "| missed | false | GOSPA after a rigid fit [m] (map turned by) | final joint NEES (dof) "
             "| µs/step |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    gospas: dict[tuple[str, str], list[float]] = {}
    shapes: dict[tuple[str, str], list[float]] = {}
    rmses: dict[tuple[str, str], list[float]] = {}
    failures: list[str] = []
    t0, c0 = time.perf_counter(), time.process_time()
    for robot in (1, 2, 3, 4, 5):
        data = load_mrclam(folder, robot)
        cal = calibration_for(data, "others")
        runs = [("barcodes", run_mrclam(data, flt, calibration=cal, slam=True, graph=bool(blind)))]
        if blind:
            runs.append(("none", run_mrclam(data, blind, calibration=cal, slam=True, unknown_ids=True)))
        for ids, res in runs:
            ev, figs = res.evaluate(), mrclam_slam_figures(res)
            print(f"SLAM robot {robot} IDs {ids}: " + ", ".join(
                f"{f} {r.get('pos_rmse_m')} {(figs.get(f) or {}).get('map_gospa_m')}"
                for f, r in ev.items()), file=sys.stderr, flush=True)
            for f, r in ev.items():
                fig = figs.get(f)
                if r.get("mse_x") is None or fig is None:
                    failures.append(f"robot {robot} {f} (IDs: {ids}): "
                                    f"{r.get('failed') or 'no score'}")
                    lines.append(f"| {robot} | {f} | {map_cell(f, res.map_given[f])} | {ids} "
                                 "| failed | | | | | | | | |")
                    continue
                iv = mrclam_intervals(res, f)
                rmses.setdefault((f, ids), []).append(r["pos_rmse_m"])
                given = fig["map_given"]
                if not given:
                    gospas.setdefault((f, ids), []).append(fig["map_gospa_m"])
                    if fig["map_gospa_aligned_m"] is not None:
                        shapes.setdefault((f, ids), []).append(fig["map_gospa_aligned_m"])
                aligned = ("-" if given or fig["map_gospa_aligned_m"] is None else
                           f"{fig['map_gospa_aligned_m']:.3f} ({fig['map_rotation_deg']:+.1f}°)")
                joint = ("-" if fig["joint_nees"] is None
                         else f"{fig['joint_nees']:.3g} ({fig['joint_dof']})")
                lines.append(
                    f"| {robot} | {f} | {map_cell(f, given)} | {ids} "
                    f"| {with_iv(r['pos_rmse_m'], iv['rmse'], '.3f')} "
                    f"| {anees_cell(r.get('anees'), iv['anees'])} "
                    + ("| | | | | |" if given else
                       f"| {fig['map_gospa_m']:.3f} | {fig['map_landmarks']} | {fig['map_missed']} "
                       f"| {fig['map_false']} | {aligned} |")
                    + f" {joint} | {fmt(r.get('us_per_step'), '.1f')} |")
    over = ["| filter | IDs | pos RMSE over robots [m] | map GOSPA, mean over robots [m] | range [m] "
            "| GOSPA after a rigid fit, mean [m] | range [m] |", "|---|---|---|---|---|---|---|"]

    def mean_cells(g: list[float] | None) -> str:
        if not g:
            return "- | |"
        iv = ratio_of_sums(np.array(g), np.ones(len(g)))
        return f"{with_iv(float(np.mean(g)), iv, '.3f')} | {min(g):.3f}-{max(g):.3f} |"

    for (f, ids), vals in rmses.items():
        over.append(f"| {f} | {ids} | {min(vals):.3f}-{max(vals):.3f} | {mean_cells(gospas.get((f, ids)))} "
                    f"{mean_cells(shapes.get((f, ids)))}")
    took, cpu = time.perf_counter() - t0, time.process_time() - c0
    return [
        *md,
        f"{folder.name}, all five robots, whole runs. `beacon-sim mrclam DIR --robot N --slam "
        f"--graph --headless` (and `--unknown-ids` for the rows without IDs): `ekf_slam` and "
        f"`fastslam` "
        f"(FastSLAM 2.0, 100 particles, the default) are **not given the landmark map** (no anchors;"
        f" the known start pose fixes the frame) and map the 15 landmarks themselves; `ekf` is the "
        f"known-map EKF of the table above on the same runs, `dead_reckoning` the odometry alone "
        f"(what a filter that learnt nothing from its readings would do); `graph_slam` (`--graph`, "
        f"with barcodes only) is graph SLAM on the same steps: the whole run's odometry and readings"
        f" as one factor graph, solved by Levenberg-Marquardt as it grows, the readings past the "
        f"gate at the optimum dropped (docs/slam.md, \"Graph SLAM on MRCLAM\"). The noise is the "
        f"same "
        f"leave-one-robot-out calibration as there (from the four other robots, the variance "
        f"inflation included; never fitted on the scored robot); no SLAM parameter was tuned on this"
        f" data (EKF-SLAM and FastSLAM gate readings with IDs at the known-map EKF's 99.9 % "
        f"point, `gate_chi2` in `MRCLAM_PARAMS`). Regenerate this section "
        f"alone with `python scripts/make_results.py --only slam` "
        f"({cpu:.0f} s of CPU on one core here, {took:.0f} s by the clock on the shared machine).",
        "",
        "Columns: IDs: `barcodes` (each reading names its landmark) or `none` (`--unknown-ids`: "
        "the filters associate). Pos RMSE and pose ANEES: brackets are 95 % block-bootstrap "
        f"intervals over the run's {MRCLAM_BLOCK_S:g} s blocks, as in the MRCLAM table. Map "
        f"GOSPA: the final map against the 15 surveyed landmarks (cut-off c = {GOSPA_CUTOFF_M:g} m: "
        "a landmark farther than that from every surveyed one is false, each missed or false "
        "one costs c/sqrt(2); a root of a sum over the map: 15 landmarks each 10 cm off give "
        "0.39 m), one number per run. Final joint NEES: over the final pose and every mapped "
        "landmark (FastSLAM's is EKF-SLAM's covariance linearised at its particles' mean; `-` "
        "when the ground truth "
        "ends before the run's last estimate), chi-square with the dof shown "
        "for a consistent filter. GOSPA after a rigid fit: the same after the rotation and shift "
        "that best fit the map onto the survey (landmarks paired by ID, or by GOSPA without IDs): "
        "the map's shape error, without the error of its frame (a map turned as a whole, which "
        "nothing in the readings reveals when no landmark is known; three fitted parameters, so "
        "slightly optimistic), with the rotation that fit applied; `-` with fewer than two "
        "landmarks paired.", "",
        *lines, "",
        "Over the robots: the range of the position RMSE, and the map GOSPA's mean with a 95 % "
        "bootstrap interval **over the five robots** (five numbers: a coarse interval; the "
        "landmarks of one map are not independent, they share the pose errors of the moments "
        "they were mapped in, so the map is not resampled landmark by landmark):", "",
        *over, "",
        *([f"Switched off (no score): {'; '.join(failures)}.", ""] if failures else []),
        "What it shows is discussed in [slam.md](slam.md#slam-on-real-data-mrclam).", ""]


def fig_mrclam(ctx: Context) -> Figure:
    """Seed 001 on real data: every MRCLAM robot, leave-one-robot-out (no seeds)."""
    return Figure(mrclam_section(ctx.mrclam, ctx.have)[2:])


def fig_mrclam_association(ctx: Context) -> Figure:
    """The known-map filters on every MRCLAM robot with and without barcodes (no seeds)."""
    return Figure(association_section(ctx.mrclam)[2:])


def fig_mrclam_slam(ctx: Context) -> Figure:
    """EKF-SLAM and FastSLAM on every MRCLAM robot (no seeds)."""
    return Figure(slam_section(ctx.mrclam, ctx.have)[2:])
