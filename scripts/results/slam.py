"""The SLAM figures on simulated worlds: ``slam_loop``, bearing-only SLAM, FastSLAM without
IDs, FastSLAM's reported covariance on a benign ring, and graph SLAM."""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from beacon_sim.core.scenario import load_scenario

from .common import Check, Context, Figure, helper_module, mean_interval, with_iv

#: slam_loop's cases: (filter, IDs hidden, parameters, label).
SLAM_LOOP_CASES = (
    ("ekf", False, None, "`ekf` given the true map"),
    ("ekf_slam", False, None, "`ekf_slam`"),
    ("ekf_slam", True, None, "`ekf_slam`, no IDs (JCBB)"),
    ("fastslam", False, None, "`fastslam` (100 particles, linearised covariance)"),
    ("fastslam", False, {"covariance": "particles"}, "`fastslam`, `covariance = \"particles\"`"),
    ("fastslam", True, None, "`fastslam`, no IDs (particle covariance)"),
)


def slam_loop_seed(seed: int, have: set[str]) -> tuple[dict, np.ndarray, np.ndarray]:
    """One seeded run of ``slam_loop`` for every case of ``SLAM_LOOP_CASES``: per case label
    the ATE [m], the map GOSPA [m] (None with the map given), the final pose NEES and the
    joint NEES per dof (None without IDs); and the true path and the controls."""
    from beacon_sim.core.clutter import ClutterSpec, hide_ids_all
    from beacon_sim.core.simulation import Simulation
    from beacon_sim.evaluation.slam_metrics import ate, gospa, joint_nees
    from beacon_sim.hosting.loading import build_filter

    sc = load_scenario("slam_loop")
    truth_xy = {b.id: (b.x, b.y) for b in sc.world.beacons}
    out: dict[str, dict[str, float | None]] = {}
    sim_truth = ctl_all = None
    for spec, hide, params, label in [c for c in SLAM_LOOP_CASES if c[0] in have]:
        scen = dataclasses.replace(sc, map_known=True) if spec == "ekf" else sc
        flt = build_filter(spec, scen, seed, params=params)
        sim = Simulation(scen, seed)
        rng = np.random.default_rng(seed + 7)   # which reading hides which ID
        est, tru, ctl = [], [np.array(scen.initial_pose)], []
        for _ in range(round(scen.duration / scen.dt)):
            st = sim.step()
            ms = st.measurements
            if hide:
                fired = [x for x in scen.sensors if x.name in {m.sensor for m in ms}]
                ms, _ = hide_ids_all(ms, fired, {x.name: ClutterSpec() for x in fired}, rng)
            flt.predict(st.control, st.dt)
            flt.update(ms)
            est.append(flt.estimate()[0])
            tru.append(st.true_pose)
            ctl.append((st.control.v, st.control.omega))
        if sim_truth is None:
            sim_truth, ctl_all = np.array(tru), np.array(ctl)
        m, P = flt.estimate()
        d = sim_truth[-1] - m
        d[2] = (d[2] + math.pi) % (2 * math.pi) - math.pi
        row: dict[str, float | None] = {"ate": ate(np.array(est), sim_truth[1:]),
                                        "nees": float(d @ np.linalg.solve(P, d)),
                                        "gospa": None, "jnees": None}
        if spec != "ekf":
            row["gospa"] = gospa(flt.landmarks().means, sc.world.beacon_xy, c=1.0).value
        if spec != "ekf" and not hide:  # the joint NEES over 3 + 2 M, per degree of freedom
            jm, jP, jids = flt.joint()
            row["jnees"] = joint_nees(jm, jP, jids, sim_truth[-1], truth_xy) / jm.size
        out[label] = row
    return out, sim_truth, ctl_all


def fig_slam_loop(ctx: Context) -> Figure:
    """EKF-SLAM and FastSLAM 2.0 on ``slam_loop`` over seeded runs: the path's ATE, the final
    map's GOSPA (c = 1 m), the final pose NEES and the joint NEES per degree of freedom,
    with and without IDs, beside the EKF given the map and the known-map PCRB."""
    from concurrent.futures import ProcessPoolExecutor

    from beacon_sim.evaluation.intervals import ratio_of_sums
    from beacon_sim.evaluation.pcrb import pcrb

    t0 = time.perf_counter()
    sc = load_scenario("slam_loop")
    seeds = range(ctx.seed, ctx.seed + ctx.n(20))
    with ProcessPoolExecutor(max(1, ctx.jobs)) as pool:
        done = list(pool.map(slam_loop_seed, seeds, [ctx.have] * len(seeds)))
    res: dict[str, dict[str, list[float]]] = {}
    for rows_of_seed, _, _ in done:
        for label, row in rows_of_seed.items():
            acc = res.setdefault(label, {"ate": [], "gospa": [], "nees": [], "jnees": []})
            for k, v in row.items():
                if v is not None:
                    acc[k].append(v)
    truths = [t for _, t, _ in done]
    controls = [c for _, _, c in done]
    B = pcrb(sc, np.stack(truths), np.stack(controls))
    floor = list(np.sqrt(np.mean(B[..., 0, 0] + B[..., 1, 1], axis=1)))
    checks: dict[str, Check] = {}

    def cell(v: list[float], what: str, spec: str = ".3f") -> str:
        if not v:
            return ""
        a = np.asarray(v, dtype=float)
        iv = ratio_of_sums(a, np.ones(len(a)))
        checks[what] = (float(a.mean()), iv)
        return with_iv(float(a.mean()), iv, spec)

    rows = [f"| {label} | {cell(r['ate'], f'{label} ATE [m]')} "
            f"| {cell(r['gospa'], f'{label} map GOSPA [m]') or '(map given)'} "
            f"| {cell(r['nees'], f'{label} final pose NEES', '.3g')} "
            f"| {cell(r['jnees'], f'{label} joint NEES / dof', '.3g')} |" for label, r in res.items()]
    rows.append(f"| known-map PCRB (floor for the path) | {cell(floor, 'known-map PCRB [m]')} | | | |")
    checks.pop("known-map PCRB [m]")   # the bound along the true paths: not a filter's figure
    return Figure([
        f"`slam_loop`, {len(seeds)} seeded runs (seeds {ctx.seeds(20)}); each filter sees the same "
        "simulated runs; \"no IDs\": the same readings with the IDs hidden, no clutter. Means over "
        "the runs; brackets: 95 % bootstrap intervals over the runs. ATE: the path's RMS position "
        "error; map GOSPA (c = 1 m): the final map against the beacons; final pose NEES: 3 for an "
        "honest filter; joint NEES / dof: over the final pose and every landmark, divided by "
        "3 + 2 M (1 for an honest filter). What it shows is discussed in "
        f"[slam.md](slam.md#on-slam_loop) ({time.perf_counter() - t0:.0f} s here).", "",
        "| filter | ATE [m] | map GOSPA, c = 1 m [m] | final pose NEES (3 dof) | final joint NEES / dof |",
        "|---|---|---|---|---|", *rows, ""], checks)


#: slam_bearing_only's checked times [s] (joint ANEES) and its two initialisations.
BEARING_ONLY_TIMES = (10.0, 20.0, 40.0)


BEARING_ONLY_INITS = ("delayed", "inverse_depth")


def bearing_only_seed(args: tuple[str, int]) -> dict:
    """One seeded run of ``slam_bearing_only`` with EKF-SLAM's ``bearing_init`` = ``init``:
    the joint NEES and its dof at each of ``BEARING_ONLY_TIMES``, the landmarks on the map at
    the first, and the final map's RMS error over its landmarks [m]."""
    from beacon_sim.core.simulation import Simulation
    from beacon_sim.evaluation.slam_metrics import joint_nees
    from beacon_sim.hosting.loading import build_filter

    init, seed = args
    sc = load_scenario("slam_bearing_only")
    truth = {b.id: (b.x, b.y) for b in sc.world.beacons}
    ticks = {round(t / sc.dt): t for t in BEARING_ONLY_TIMES}
    flt = build_filter("ekf_slam", sc, seed, params={"bearing_init": init})
    sim = Simulation(sc, seed)
    out: dict = {"nees": {}, "dof": {}}
    for _ in range(round(sc.duration / sc.dt)):
        st = sim.step()
        flt.predict(st.control, st.dt)
        flt.update(st.measurements)
        if st.tick in ticks:
            mu, P, ids = flt.joint()
            out["nees"][ticks[st.tick]] = joint_nees(mu, P, ids, st.true_pose, truth)
            out["dof"][ticks[st.tick]] = mu.size
            if ticks[st.tick] == BEARING_ONLY_TIMES[0]:
                out["mapped_first"] = len(flt.landmarks().ids)
    lm = flt.landmarks()
    out["map_rms"] = math.sqrt(np.mean([np.sum((m - np.asarray(truth[int(b)])) ** 2)
                                        for b, m in zip(lm.ids, lm.means, strict=True)]))
    out["mapped"] = len(lm.ids)
    return out


def fig_bearing_only(ctx: Context) -> Figure:
    """Bearing-only EKF-SLAM on ``slam_bearing_only``: inverse depth against the delayed
    initialisation, the joint ANEES at 10, 20 and 40 s against its 99 % band, the landmarks
    mapped at 10 s and the final map error, over seeded runs."""
    from concurrent.futures import ProcessPoolExecutor

    from beacon_sim.evaluation.intervals import ratio_of_sums
    from beacon_sim.evaluation.slam_metrics import joint_anees_band

    seeds = list(range(ctx.seed, ctx.seed + ctx.n(20)))
    cases = [(init, s) for init in BEARING_ONLY_INITS for s in seeds]
    with ProcessPoolExecutor(max(1, ctx.jobs)) as pool:
        done = dict(zip(cases, pool.map(bearing_only_seed, cases), strict=True))
    checks: dict[str, Check] = {}
    rows = []
    for init in BEARING_ONLY_INITS:
        runs = [done[(init, s)] for s in seeds]
        cells = []
        for t in BEARING_ONLY_TIMES:
            nees = np.array([r["nees"][t] for r in runs])
            dof = np.array([r["dof"][t] for r in runs], dtype=float)
            anees, iv = float(nees.sum() / dof.sum()), ratio_of_sums(nees, dof)
            lo, hi = joint_anees_band(1, int(dof.sum()), 0.99)
            checks[f"`{init}` joint ANEES at {t:g} s"] = (anees, iv)
            inside = "" if lo <= anees <= hi else ", outside"
            cells.append(f"{with_iv(anees, iv, '.2f')} ({lo:.2f}-{hi:.2f}{inside})")
        first = np.array([r["mapped_first"] for r in runs], dtype=float)
        err = np.array([r["map_rms"] for r in runs])
        checks[f"`{init}` landmarks on the map at {BEARING_ONLY_TIMES[0]:g} s"] = (
            float(first.mean()), mean_interval(first))
        checks[f"`{init}` final map error, RMS [m]"] = (float(err.mean()), mean_interval(err))
        all_mapped = sum(r["mapped"] == 5 for r in runs)
        rows.append(f"| `\"{init}\"` | {' / '.join(cells)} "
                    f"| {with_iv(float(first.mean()), mean_interval(first), '.1f')} of 5 "
                    f"| {all_mapped}/{len(runs)} "
                    f"| {with_iv(float(err.mean()), mean_interval(err), '.4f')} |")
    return Figure([
        f"`slam_bearing_only` as shipped (five beacons to map, two anchors, a 360-degree bearing "
        f"sensor, 40 s), `ekf_slam` with each `bearing_init`, {len(seeds)} runs, seeds "
        f"{ctx.seeds(20)} (the same runs for both). Joint ANEES: the joint NEES over the pose and "
        "the mapped Euclidean landmarks, summed over the runs and divided by the summed degrees "
        "of freedom (1 for an honest filter; in parentheses its 99 % chi-square band for those "
        "degrees of freedom); map error: the final map's RMS "
        "distance to the true beacons, mean over the runs. Brackets: 95 % bootstrap intervals "
        "over the runs. What it shows is discussed in [slam.md](slam.md#bearing-only-slam-slam_bearing_only)"
        ".", "",
        "| `bearing_init` | joint ANEES at 10 / 20 / 40 s | landmarks on the map at 10 s "
        "| runs with all five mapped at 40 s | final map error, RMS [m] |",
        "|---|---|---|---|---|", *rows, ""], checks)


def fastslam_association_seed(args: tuple[str, int]) -> tuple[float, float, float]:
    """``benchmarks/bench_slam.py``'s ``association_seed``: one seeded look-alike run."""
    return helper_module("benchmarks", "bench_slam").association_seed(*args)


def fig_fastslam_association(ctx: Context) -> Figure:
    """FastSLAM's per-particle association without IDs: ML against JCBB on five look-alike
    pairs with clutter (``bench_slam.py --association``'s case) over seeded runs."""
    from concurrent.futures import ProcessPoolExecutor

    seeds = list(range(ctx.seed, ctx.seed + ctx.n(20)))
    cases = [(m, s) for m in ("ml", "jcbb") for s in seeds]
    with ProcessPoolExecutor(max(1, ctx.jobs)) as pool:
        done = dict(zip(cases, pool.map(fastslam_association_seed, cases), strict=True))
    checks: dict[str, Check] = {}
    rows = []
    for method, label in (("ml", "`\"ml\"` (default)"), ("jcbb", "`\"jcbb\"`")):
        fr, gs, cpu = (np.array(v) for v in zip(*(done[(method, s)] for s in seeds), strict=True))
        ivf, ivg = mean_interval(fr), mean_interval(gs)
        checks[f"{method}: share of right associations"] = (float(fr.mean()), ivf)
        checks[f"{method}: map GOSPA [m]"] = (float(gs.mean()), ivg)
        rows.append(f"| {label} | {with_iv(float(fr.mean()), ivf, '.3f')} "
                    f"| {with_iv(float(gs.mean()), ivg, '.3f')} | {np.median(cpu):.1f} |")
    return Figure([
        "FastSLAM 2.0 without IDs, 30 particles, on five pairs of look-alike beacons 0.4 m apart "
        "on a 4 m ring with clutter (0.5 false readings a tick), a poor gyro, 20 s "
        f"(`benchmarks/bench_slam.py --association`'s case), {len(seeds)} runs, seeds "
        f"{ctx.seeds(20)} (the same runs for both). A reading is associated right when a "
        "particle gives it to its landmark nearest the reading's beacon, or clutter to none, "
        "weighted by the particles' weights; map GOSPA (c = 1 m): the final map against the "
        "beacons. Means over the runs; brackets: 95 % bootstrap intervals over the runs; CPU: "
        "the median over the runs (measured, not reproducible). What it shows is discussed in "
        "[slam.md](slam.md#fastslam-20-fastslam).", "",
        "| per-particle association | right associations | map GOSPA, c = 1 m [m] | CPU per tick [ms] |",
        "|---|---|---|---|", *rows, ""], checks)


def ring_slam_scenario(n_beacons: int, duration: float, *, bearing_only: bool = False,
                       anchors: tuple[int, ...] = ()):
    """The benign SLAM ring of ``tests/filters/test_fastslam_covariance.py`` (``tests/slam_helpers.py``):
    a 3 m circle in a 12 m room, ``n_beacons`` on a 4.5 m ring all in view (8 m), range-bearing
    0.05 m / 0.02 rad at 10 Hz (bearings only with ``bearing_only``), modest motion noise, no
    map given but the ``anchors`` (beacon IDs), the filters told the true noise."""
    from beacon_sim.core.scenario import parse_scenario

    beacons = [{"id": i + 1, "x": 6.0 + 4.5 * math.cos(2 * math.pi * i / n_beacons + 0.3),
                "y": 6.0 + 4.5 * math.sin(2 * math.pi * i / n_beacons + 0.3)} for i in range(n_beacons)]
    for b in beacons:
        if b["id"] in anchors:
            b["anchor"] = True
    sensor = {"name": "beacons", "kind": "bearing" if bearing_only else "range_bearing", "period": 0.1,
              "max_range": 8.0, "detection_prob": 1.0, "bearing_std": 0.02}
    if not bearing_only:
        sensor["range_std"] = 0.05
    return parse_scenario({
        "name": "ring_slam", "dt": 0.1, "duration": duration, "seed": 1,
        "world": {"bounds": [0.0, 0.0, 12.0, 12.0], "beacons": beacons},
        "robot": {"initial_pose": [9.0, 6.0, math.pi / 2],
                  "motion_noise": {"v_std": 0.02, "v_frac": 0.05, "omega_std": 0.03, "omega_frac": 0.0,
                                   "pose_std": [0.0, 0.0, 0.0]}},
        "sensors": [sensor],
        "driver": {"kind": "circle", "radius": 3.0, "speed": 0.5},
        "initial_belief": {"std": [0.01, 0.01, 0.005]},
        "model": {"map": "unknown"}}, "ring_slam.toml")


#: The ring figure's cases: (filter, parameters, label).
RING_CASES = (("fastslam", {"n_particles": 50, "covariance": "particles"}, '`fastslam`, `"particles"`'),
              ("fastslam", {"n_particles": 50, "covariance": "linearised"}, '`fastslam`, `"linearised"`'),
              ("ekf_slam", None, "`ekf_slam`"))


def ring_seed(seed: int) -> list[tuple[float, int]]:
    """One seeded 10 s run of the ring per ``RING_CASES``: the final joint NEES and its dof."""
    from beacon_sim.core.simulation import Simulation
    from beacon_sim.evaluation.slam_metrics import joint_nees
    from beacon_sim.hosting.loading import build_filter

    sc = ring_slam_scenario(6, 10.0)
    truth = {b.id: (b.x, b.y) for b in sc.world.beacons}
    out = []
    for spec, params, _ in RING_CASES:
        flt = build_filter(spec, sc, seed, params=params)
        sim = Simulation(sc, seed)
        for _ in range(round(sc.duration / sc.dt)):
            st = sim.step()
            flt.predict(st.control, st.dt)
            flt.update(st.measurements)
        mu, P, ids = flt.joint()
        out.append((float(joint_nees(mu, P, ids, st.true_pose, truth)), int(mu.size)))
    return out


def fig_fastslam_ring(ctx: Context) -> Figure:
    """FastSLAM 2.0's final joint NEES on the benign ring with the particle set's own
    covariance and with the linearised one, beside EKF-SLAM on the same runs."""
    from concurrent.futures import ProcessPoolExecutor

    from beacon_sim.evaluation.intervals import ratio_of_sums
    from beacon_sim.evaluation.slam_metrics import joint_anees_band

    n = ctx.n(20)
    seeds = list(range(ctx.seed, ctx.seed + n))
    with ProcessPoolExecutor(max(1, ctx.jobs)) as pool:
        res = list(pool.map(ring_seed, seeds))
    checks: dict[str, Check] = {}
    rows = []
    for j, (_, _, label) in enumerate(RING_CASES):
        e = np.array([r[j][0] for r in res])
        d = np.array([r[j][1] for r in res], dtype=float)
        anees, iv = float(e.sum() / d.sum()), ratio_of_sums(e, d)
        lo, hi = joint_anees_band(1, int(d.sum()), 0.99)
        checks[f"{label.replace('`', '')}: joint ANEES per dof"] = (anees, iv)
        where = "inside" if lo <= anees <= hi else "above" if anees > hi else "below"
        rows.append(f"| {label} | {with_iv(anees, iv, '.3g')} | {lo:.2f}-{hi:.2f} | {where} |")
    return Figure([
        f"The benign ring of `tests/filters/test_fastslam_covariance.py` (a 3 m circle, six "
        f"beacons on a 4.5 m ring all in view, range-bearing 0.05 m / 0.02 rad, no map given, "
        f"known IDs), {n} runs of 10 s, seeds {ctx.seeds(20)}; FastSLAM 2.0 with 50 particles and "
        "each `covariance`, EKF-SLAM on the same runs. The final joint NEES over the pose and "
        "the six landmarks (15 dof a run), summed over the runs and divided by the summed dof "
        "(1 for an honest filter), against its 99 % chi-square band. Brackets: 95 % bootstrap "
        "intervals over the runs. What it shows is discussed in "
        "[slam.md](slam.md#fastslam-20-fastslam).", "",
        "| filter | joint ANEES / dof | 99 % band | against it |", "|---|---|---|---|", *rows, ""], checks)


def fig_graph_slam(ctx: Context) -> Figure:
    """Graph SLAM (Gauss-Newton over the whole drive) against EKF-SLAM and odometry on
    ``slam_loop``: the ATE at the graph's pose ticks, pooled over runs, and the map GOSPA."""
    from beacon_sim.core.scenario import load_any_scenario
    from beacon_sim.evaluation.graph_slam_run import PEER, run_sums, solve_drive
    from beacon_sim.evaluation.intervals import ratio_of_sums

    sc = load_any_scenario("slam_loop").robots[0].scenario
    k = 20
    t0 = time.process_time()
    sums = []
    for seed in range(ctx.seed, ctx.seed + ctx.n(k)):
        res, dg, solver, _ = solve_drive(sc, seed, None)
        sums.append(run_sums(sc, res, dg, solver))
    cpu = time.process_time() - t0
    n = np.array([s["n"] for s in sums], dtype=float)
    checks: dict[str, Check] = {}
    rows = []
    for key, label in (("graph", "graph SLAM (Gauss-Newton)"), (PEER, "EKF-SLAM"), ("odometry", "odometry")):
        v = np.array([s[key] for s in sums], dtype=float)
        ate, iv = float(np.sqrt(v.sum() / n.sum())), ratio_of_sums(v, n, sqrt=True)
        checks[f"{key} ATE [m]"] = (ate, iv)
        cell = "-"
        if f"{key}_gospa" in sums[0]:
            g = [s[f"{key}_gospa"] for s in sums]
            checks[f"{key} map GOSPA [m]"] = (float(np.mean(g)), mean_interval(g))
            cell = with_iv(float(np.mean(g)), mean_interval(g), ".3f")
        rows.append(f"| {label} | {with_iv(ate, iv, '.3f')} | {cell} |")
    return Figure([
        f"`slam_loop`, {ctx.n(k)} runs, seeds {ctx.seeds(k)} (`python scripts/graph_slam_results.py "
        f"--first-seed {ctx.seed} --runs {ctx.n(k)}`, {cpu:.0f} s of CPU here): graph SLAM solves "
        "the whole drive's factor graph by Gauss-Newton; EKF-SLAM and odometry on the same "
        "drive. ATE: the position error at the graph's pose ticks, pooled over the runs; map "
        "GOSPA (c = 1 m): the final map against the beacons, the mean over runs. Brackets: 95 % "
        "bootstrap intervals over the runs. What it shows is discussed in [smoothing.md]"
        "(smoothing.md#from-a-drive).", "",
        "| estimate on `slam_loop` | ATE [m] | map GOSPA [m] |", "|---|---|---|", *rows, ""], checks)


#: The bearing-only ring's cases: (``ekf_slam`` parameters, label).
BEARING_RING_CASES = (
    ({"bearing_init": "delayed", "min_parallax": 0.1}, '`"delayed"`, `min_parallax` 0.1'),
    ({"bearing_init": "delayed", "min_parallax": 0.3}, '`"delayed"`, `min_parallax` 0.3 (default)'),
    ({"bearing_init": "inverse_depth"}, '`"inverse_depth"`'))


def bearing_ring_seed(seed: int) -> list[tuple[float, int, float, int]]:
    """One seeded 20 s run of the bearing-only ring (six beacons, anchors 1 and 2) per
    ``BEARING_RING_CASES``: the final joint NEES and its dof (the pose and the Euclidean
    landmarks), the mapped landmarks' RMS distance to their beacons [m] and how many."""
    from beacon_sim.core.simulation import Simulation
    from beacon_sim.evaluation.slam_metrics import joint_nees
    from beacon_sim.hosting.loading import build_filter

    sc = ring_slam_scenario(6, 20.0, bearing_only=True, anchors=(1, 2))
    truth = {b.id: (b.x, b.y) for b in sc.world.beacons}
    out = []
    for params, _ in BEARING_RING_CASES:
        flt = build_filter("ekf_slam", sc, seed, params=params)
        sim = Simulation(sc, seed)
        for _ in range(round(sc.duration / sc.dt)):
            st = sim.step()
            flt.predict(st.control, st.dt)
            flt.update(st.measurements)
        mu, P, ids = flt.joint()
        lm = flt.landmarks()
        d2 = [float(np.sum((m - np.asarray(truth[int(i)])) ** 2))
              for i, m in zip(lm.ids, lm.means, strict=True) if int(i) not in (1, 2)]
        out.append((float(joint_nees(mu, P, ids, st.true_pose, truth)), int(mu.size),
                    float(np.sqrt(np.mean(d2))) if d2 else math.nan, len(d2)))
    return out


def fig_bearing_ring(ctx: Context) -> Figure:
    """Bearing-only EKF-SLAM on a benign ring: the final joint ANEES with the delayed
    initialisation's parallax threshold at 0.1 and 0.3 rad, and inverse depth; the map error."""
    from concurrent.futures import ProcessPoolExecutor

    from beacon_sim.evaluation.intervals import ratio_of_sums
    from beacon_sim.evaluation.slam_metrics import joint_anees_band

    n = ctx.n(40)
    seeds = list(range(ctx.seed, ctx.seed + n))
    with ProcessPoolExecutor(max(1, ctx.jobs)) as pool:
        res = list(pool.map(bearing_ring_seed, seeds))
    checks: dict[str, Check] = {}
    rows = []
    for j, (_, label) in enumerate(BEARING_RING_CASES):
        e = np.array([r[j][0] for r in res])
        d = np.array([r[j][1] for r in res], dtype=float)
        err = np.array([r[j][2] for r in res])
        mapped = sum(r[j][3] == 4 for r in res)
        anees, iv = float(e.sum() / d.sum()), ratio_of_sums(e, d)
        lo, hi = joint_anees_band(1, int(d.sum()), 0.99)
        name = label.replace("`", "").replace('"', "")
        checks[f"{name}: joint ANEES per dof"] = (anees, iv)
        ok = np.isfinite(err)
        miv = mean_interval(err[ok]) if ok.sum() > 1 else None
        if ok.sum() > 1:
            checks[f"{name}: map error [m]"] = (float(err[ok].mean()), miv)
        where = "inside" if lo <= anees <= hi else "above" if anees > hi else "below"
        rows.append(f"| {label} | {with_iv(anees, iv, '.3g')} | {lo:.2f}-{hi:.2f} | {where} "
                    f"| {with_iv(float(err[ok].mean()) if ok.any() else None, miv, '.4f')} | {mapped}/{n} |")
    return Figure([
        f"The benign ring with bearings only (a 3 m circle, six beacons on a 4.5 m ring all in view, "
        f"bearings 0.02 rad at 10 Hz, beacons 1 and 2 anchors, the other four to map), {n} runs of "
        f"20 s, seeds {ctx.seeds(40)}, `ekf_slam` with each setting on the same runs. Joint ANEES: "
        "the final joint NEES over the pose and the Euclidean landmarks, summed over the runs and "
        "divided by the summed dof (1 for an honest filter), against its 99 % chi-square band; map "
        "error: the mapped landmarks' RMS distance to their beacons, the mean over runs. Brackets: "
        "95 % bootstrap intervals over the runs. What it shows is discussed in "
        "[slam.md](slam.md#ekf-slam-ekf_slam).", "",
        "| `bearing_init` | joint ANEES / dof | 99 % band | against it | map error [m] "
        "| runs with all four mapped |",
        "|---|---|---|---|---|---|", *rows, ""], checks)
