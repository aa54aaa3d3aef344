"""Step cost of the SLAM filters with 50 landmarks on their maps, against the 16.7 ms of a
60 FPS frame, and the cost of drawing the maps in the window.

Run:  .venv/bin/python benchmarks/bench_slam.py [--quick]
      .venv/bin/python benchmarks/bench_slam.py --accuracy 10   (the accuracy table instead)
      .venv/bin/python benchmarks/bench_slam.py --association 10   (FastSLAM ML against JCBB)

The world: 50 beacons in a 30 m x 30 m room, a range-bearing sensor of 8 m at 10 Hz (about
6-10 beacons in view), a robot on a 9 m circle. Each filter first maps all 50 beacons (six
sensor ticks with an unlimited range), then runs the timed ticks on the 8 m sensor's readings. Cost
per tick WITH readings (predict + update + estimate + landmarks(), what the window asks each
tick); the window at speed 1 runs one tick (dt = 0.05 s) every third frame, so a tick that
fits in a frame keeps 60 FPS. Known correspondence, and unknown (IDs hidden, no clutter).
Targets: EKF-SLAM (50 landmarks) and FastSLAM 2.0 (100 particles x 50 landmarks) each under
16.7 ms per tick, known correspondence. FastSLAM's per-particle JCBB (``association = "jcbb"``,
unknown correspondence only) is measured beside its default per-particle ML, no target.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import numpy as np
from figures import Clock, figure

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from beacon_sim.core.clutter import ClutterSpec, hide_ids_all
from beacon_sim.core.scenario import parse_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.hosting.loading import build_filter
from tests.slam_helpers import lookalike_pairs, weighted_correct

FRAME_MS = 1000.0 / 60.0


def scenario(max_range: float):
    rng = np.random.default_rng(50)
    xy = rng.uniform(1.0, 29.0, (50, 2))
    data = {
        "name": "bench_slam", "dt": 0.05, "duration": 600.0, "seed": 1,
        "world": {"bounds": [0.0, 0.0, 30.0, 30.0],
                  "beacons": [{"id": i + 1, "x": float(x), "y": float(y)} for i, (x, y) in enumerate(xy)]},
        "robot": {"initial_pose": [24.0, 15.0, math.pi / 2],
                  "motion_noise": {"v_std": 0.02, "v_frac": 0.05, "omega_std": 0.03}},
        "sensors": [{"name": "beacons", "kind": "range_bearing", "period": 0.1, "max_range": max_range,
                     "range_std": 0.05, "bearing_std": 0.02, "detection_prob": 0.9}],
        "driver": {"kind": "circle", "radius": 9.0, "speed": 0.5},
        "initial_belief": {"std": [0.01, 0.01, 0.005]},
        "model": {"map": "unknown"},
    }
    return parse_scenario(data, "bench_slam.toml")


def time_filter(spec: str, ticks: int, hide: bool, params=None) -> tuple[float, float, int, float]:
    """(wall ms, CPU ms per tick with readings, landmarks at the end, readings per tick)."""
    full, near = scenario(1e6), scenario(8.0)
    flt = build_filter(spec, near, 1, params=params)
    rng = np.random.default_rng(2)

    def feed(st):
        ms = st.measurements
        if hide:
            fired = [s for s in near.sensors if s.name in {m.sensor for m in ms}]
            ms, _ = hide_ids_all(ms, fired, {s.name: ClutterSpec() for s in fired}, rng)
        flt.predict(st.control, st.dt)
        flt.update(ms)
        flt.estimate()
        flt.landmarks()
        return sum(len(m) for m in ms)

    seed_sim = Simulation(full, 1)
    for _ in range(12):  # six sensor ticks with every beacon in range: all 50 mapped (and confirmed)
        feed(seed_sim.step())
    sim = Simulation(near, 1)  # the same seed: the same true path, the 8 m sensor
    for _ in range(12):
        sim.step()
    wall = cpu = 0.0
    timed = readings = 0
    while timed < ticks:  # every tick is fed; the ticks with readings are timed
        st = sim.step()
        with Clock() as c:
            got = feed(st)
        if st.measurements:
            wall, cpu, timed, readings = wall + c.wall, cpu + c.cpu, timed + 1, readings + got
    return 1e3 * wall / timed, 1e3 * cpu / timed, len(flt.landmarks().means), readings / timed


def time_drawing(reps: int) -> tuple[float, float]:
    """ms per frame for the map layer of two filters with 50 landmarks each."""
    import pygame

    from beacon_sim.app.main import App
    from beacon_sim.runs.live import Session

    app = App(Session(scenario(1e6), ["ekf_slam", "fastslam"], 1), (1280, 800), scripted=True)
    for _ in range(12):
        app.session.tick()
    from beacon_sim.app.render import polyline

    layer = app.renderer.map_layer
    names = ["ekf_slam", "fastslam"]
    assert all(len(m.means) == 50 for m in layer.maps(app.session, names).values())
    surf = pygame.Surface((1280, 800))
    with Clock() as c:
        for _ in range(reps):
            layer.draw(surf, app.view, app.session, names, app.colours, app.dashes, 4, polyline)
    return 1e3 * c.wall / reps, 1e3 * c.cpu / reps


def accuracy(runs: int) -> None:
    """``--accuracy``: the slam_loop scenario over seeded runs: the path's ATE, the map's
    GOSPA (c = 1 m) and the final pose NEES of each SLAM filter, known and unknown
    correspondence, beside the localization EKF given the true map and the known-map PCRB
    (the floor for the path), each mean with a 95 % interval (1.96 standard errors)."""
    from dataclasses import replace

    from beacon_sim.core.scenario import load_scenario
    from beacon_sim.evaluation.pcrb import pcrb
    from beacon_sim.evaluation.slam_metrics import ate, gospa, joint_nees

    sc = load_scenario("slam_loop")
    cases = [("ekf_slam", False, None), ("ekf_slam", True, None), ("fastslam", False, None),
             ("fastslam", False, {"covariance": "particles"}), ("fastslam", True, None)]
    res: dict[str, dict[str, list[float]]] = {}
    truths, controls = [], []
    truth_xy = {b.id: (b.x, b.y) for b in sc.world.beacons}
    for r in range(runs):
        seed = 1000 + r
        sim_truth = None
        for spec, hide, params in [("ekf", False, None), *cases]:
            scen = replace(sc, map_known=True) if spec == "ekf" else sc
            flt = build_filter(spec, scen, seed, params=params)
            sim = Simulation(scen, seed)
            rng = np.random.default_rng(seed + 7)
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
                sim_truth = np.array(tru)
                truths.append(sim_truth)
                controls.append(np.array(ctl))
            label = spec + (" (no IDs)" if hide else "") + (" (particle cov)" if params else "")
            row = res.setdefault(label, {"ate": [], "gospa": [], "nees": [], "jnees": []})
            e = np.array(est)
            row["ate"].append(ate(e, sim_truth[1:]))
            m, P = flt.estimate()
            d = sim_truth[-1] - m
            d[2] = (d[2] + math.pi) % (2 * math.pi) - math.pi
            row["nees"].append(float(d @ np.linalg.solve(P, d)))
            if spec != "ekf":
                row["gospa"].append(gospa(flt.landmarks().means, sc.world.beacon_xy, c=1.0).value)
            if spec != "ekf" and not hide:  # the joint NEES over 3 + 2 M, per degree of freedom
                jm, jP, jids = flt.joint()
                row["jnees"].append(joint_nees(jm, jP, jids, sim_truth[-1], truth_xy) / jm.size)
    B = pcrb(sc, np.stack(truths), np.stack(controls))
    floor = np.sqrt(np.mean(B[..., 0, 0] + B[..., 1, 1], axis=1))

    def ci(v, fmt=".3f"):
        v = np.asarray(v, dtype=float)
        half = 1.96 * v.std(ddof=1) / math.sqrt(len(v)) if len(v) > 1 else math.nan
        return f"{v.mean():{fmt}} +- {half:{fmt}}"

    print(f"slam_loop, {runs} seeded runs (seeds 1000..{999 + runs}), 95 % intervals")
    print(f"{'filter':<32} {'ATE [m]':>16} {'GOSPA map [m]':>16} {'final NEES (3 dof)':>20} "
          f"{'joint NEES / dof':>18}")
    for label, row in res.items():
        print(f"{label:<32} {ci(row['ate']):>16} {ci(row['gospa']) if row['gospa'] else '(map given)':>16} "
              f"{ci(row['nees'], '.3g'):>20} {ci(row['jnees'], '.3g') if row['jnees'] else '':>18}")
        if row["jnees"]:
            figure(f"slam_loop {label}: final joint NEES per degree of freedom (1 if honest)",
                   float(np.mean(row["jnees"])), "")
    print("joint NEES / dof: the final joint NEES over the pose and the map divided by 3 + 2 M, "
          "averaged over the runs (1 for an honest filter; the band for 10 runs of 27 dof is about 0.82-1.2)")
    print(f"{'known-map PCRB':<32} {ci(floor):>16}   (RMS of sqrt(Pxx + Pyy) over the path)")


def association_seed(method: str, seed: int) -> tuple[float, float, float]:
    """One seeded run of ``--association``'s case (FastSLAM with per-particle ``method``,
    ``"ml"`` or ``"jcbb"``, 30 particles, on five look-alike pairs with 0.5 clutter readings
    a tick, 20 s): the weighted share of right (reading, particle) associations (a beacon's
    reading given to the particle's landmark nearest that beacon; clutter given to none),
    the final map's GOSPA (c = 1 m) [m] and the CPU per tick [ms]
    (``scripts/make_results.py --only fastslam_association`` runs it on the docs' seeds)."""
    from beacon_sim.evaluation.slam_metrics import gospa

    sc = lookalike_pairs(20.0)
    xy, ids = sc.world.beacon_xy, np.asarray(sc.world.beacon_ids)
    flt = build_filter("fastslam", sc, seed, params={"n_particles": 30, "association": method})
    sim = Simulation(sc, seed)
    rng = np.random.default_rng(seed + 1000)
    good = total = 0.0
    ticks = 0
    with Clock() as c:
        for _ in range(round(sc.duration / sc.dt)):
            st = sim.step()
            fired = [x for x in sc.sensors if x.name in {m.sensor for m in st.measurements}]
            spec = {x.name: ClutterSpec(0.5) for x in fired}
            ms, truth = hide_ids_all(st.measurements, fired, spec, rng)
            flt.predict(st.control, st.dt)
            flt.update(ms)
            ticks += 1
            if "beacons" not in truth:
                continue
            g, k = weighted_correct(flt, truth["beacons"], xy, ids)
            good, total = good + g, total + k
    return good / total, gospa(flt.landmarks().means, xy, c=1.0).value, 1e3 * c.cpu / ticks


def association(runs: int) -> None:
    """``--association``: FastSLAM's per-particle ML against per-particle JCBB on five
    look-alike pairs with clutter (0.5 a tick), 20 s, 30 particles, over seeded runs
    (:func:`association_seed`)."""
    print(f"lookalike pairs with clutter, {runs} seeded runs (seeds 0..{runs - 1}), 30 particles, "
          "95 % intervals")
    for method in ("ml", "jcbb"):
        fr, gs, cpu_ms = (list(v) for v in zip(*(association_seed(method, seed) for seed in range(runs)),
                                                strict=True))

        def ci(v):
            v = np.asarray(v)
            return f"{v.mean():.3f} +- {1.96 * v.std(ddof=1) / math.sqrt(len(v)):.3f}"

        print(f"{method:<5} right associations {ci(fr)}   map GOSPA [m] {ci(gs)}   "
              f"CPU ms/tick {np.mean(cpu_ms):.2f}")
        figure(f"FastSLAM {method} on look-alike pairs: share of right associations", float(np.mean(fr)), "")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--accuracy", type=int, default=0, metavar="RUNS",
                    help="also the accuracy table on slam_loop over RUNS seeded runs")
    ap.add_argument("--association", type=int, default=0, metavar="RUNS",
                    help="FastSLAM's ML against JCBB on look-alike pairs over RUNS seeded runs")
    args = ap.parse_args()
    if args.association:
        association(args.association)
        return
    if args.accuracy:
        accuracy(args.accuracy)
        return
    ticks = 20 if args.quick else 100
    print(f"{'filter':<42} {'ms/tick':>8} {'cpu ms':>8} {'landmarks':>9} {'readings':>9}")
    for spec, label, params, hides in (
            ("ekf_slam", "EKF-SLAM", None, (False, True)),
            ("fastslam", "FastSLAM 2.0, 100 particles", {"n_particles": 100}, (False, True)),
            ("fastslam", "FastSLAM 2.0 + JCBB, 100 particles", {"n_particles": 100, "association": "jcbb"},
             (True,))):
        for hide in hides:
            corr = "unknown" if hide else "known"
            wall, cpu, M, per = time_filter(spec, ticks, hide, params)
            what = f"{label}, {M} landmarks, {corr} correspondence"
            print(f"{what:<42} {wall:8.2f} {cpu:8.2f} {M:9d} {per:9.1f}")
            figure(f"{what}: tick with readings", wall, "ms", cpu=cpu,
                   target=FRAME_MS if not hide else None)
    wall, cpu = time_drawing(5 if args.quick else 30)
    print(f"{'map layer, 2 filters x 50 landmarks':<42} {wall:8.2f} {cpu:8.2f}")
    figure("window: drawing 2 maps x 50 landmarks (95 % ellipses)", wall, "ms", cpu=cpu, target=FRAME_MS)


if __name__ == "__main__":
    main()
