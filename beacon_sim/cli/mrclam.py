"""``beacon-sim mrclam [DIR] (--robot N | --team) [--filter F ...] [--duration S] [--calibrate]
[--calibration others|self] [--unknown-ids] [--slam] [--json]``: filters on one robot of a UTIAS
MRCLAM data set and seed 001's table, or on all five robots at once (``--team``: the team filters,
one row per robot). ``--unknown-ids``: the readings reach the filters without barcodes (they
associate), and the table adds how well they did. ``--slam``: the SLAM filters are not given the
landmark map, and their final maps are scored against the surveyed landmarks. Without DIR, the
data set is where ``BEACON_SIM_MRCLAM`` says (:func:`beacon_sim.io.mrclam.find_dataset`)."""

from __future__ import annotations

import argparse
import json
from typing import Any

from beacon_sim.cli.common import check_duration, check_frames, filter_params, print_failures
from beacon_sim.cli.play import parse_size
from beacon_sim.cli.tables import failed_text, fmt
from beacon_sim.errors import UsageError
from beacon_sim.io.mrclam import ROBOT_SUBJECTS, MrclamData, MrclamError, load_mrclam
from beacon_sim.runs.mrclam import (
    MRCLAM_GATE_CHI2,
    SEED_001_EKF_MSE,
    SEED_001_UKF_MSE,
    Calibration,
    calibrate,
    run_mrclam,
)


def _print_calibration(data: MrclamData, cal: Calibration) -> None:
    s = cal.stats
    print(f"MRCLAM {data.folder.name} robot {data.robot}: noise from the data ({cal.source})")
    print(f"  dropped readings: {data.dropped}")
    if s.get("windows"):
        print(f"  odometry vs ground truth over {s['windows']} windows of {cal.window_s:g} s: "
              f"forward error median {s['fwd_err_median_m']:+.4f} m, RMS "
              f"{s['fwd_err_std_m']:.4f} m (robust std {s['fwd_err_robust_std_m']:.4f}); turn error "
              f"median {s['turn_err_median_rad']:+.4f} rad, RMS {s['turn_err_std_rad']:.4f} rad "
              f"(robust std {s['turn_err_robust_std_rad']:.4f}), around the commands times "
              f"{cal.v_scale:.3f} forward and {cal.omega_scale:.3f} turning (what the robot drove "
              "per unit commanded)")
    if s.get("readings", 0) >= 5:
        print(f"  {s['readings']} readings vs ground truth: range error median "
              f"{s['range_err_median_m']:+.4f} m, RMS {s['range_err_rms_m']:.4f} m x sqrt(shared "
              f"factor {s['range_shared_factor']:.2f}) = {s['range_err_std_m']:.4f} m (robust std "
              f"{s['range_err_robust_std_m']:.4f} m), "
              f"{100 * s['range_short_tail']:.1f} % too short and {100 * s['range_long_tail']:.1f} % "
              f"too long beyond 3 std")
        print(f"  bearing error median {s['bearing_err_median_rad']:+.4f} rad, RMS "
              f"{s['bearing_err_rms_rad']:.4f} rad x sqrt(shared factor {s['bearing_shared_factor']:.2f}) "
              f"= {s['bearing_err_std_rad']:.4f} rad (robust std {s['bearing_err_robust_std_rad']:.4f}), "
              f"{100 * s['bearing_tail']:.1f} % beyond 3 robust std, "
              f"{100 * s['bearing_flipped']:.2f} % off by more than pi/2; outlier rate told "
              f"{100 * s['outlier_rate']:.1f} %")
    m = cal.motion
    print(f"  filters told (per {cal.step_dt:g} s step): v_std = {m.v_std:.4f} m/s, omega_std = "
          f"{m.omega_std:.4f} rad/s, range_std = {cal.sensor.range_std:.4f} m, bearing_std = "
          f"{cal.sensor.bearing_std:.4f} rad; EKF/UKF gate chi2 > {MRCLAM_GATE_CHI2:.2f} (99.9 %)")


def _print_run(d: dict[str, Any]) -> None:
    print(f"MRCLAM {d['dataset']} robot {d['robot']}: {d['duration_s']:.1f} s, "
          f"{d['odometry_rows']} odometry rows, {d['updates']} updates with {d['readings']} "
          f"landmark readings (dropped: {', '.join(f'{k} {v}' for k, v in d['dropped'].items())})")
    n = d["noise"]
    print(f"noise {d.get('calibration_source', 'from the data')}: v_std {n['v_std']:.4f} m/s, "
          f"omega_std {n['omega_std']:.4f} rad/s per {n['step_dt']:g} s, range_std "
          f"{n['range_std']:.4f} m, bearing_std {n['bearing_std']:.4f} rad"
          + (f"; EKF/UKF variances x {n['gaussian_inflation']:.2f}"
             if n.get("gaussian_inflation", 1.0) != 1.0 else ""))
    print(f"{'filter':<16}{'MSE x m2':>10}{'MSE y m2':>10}{'MSE th rad2':>12}{'pos RMSE m':>11}"
          f"{'head RMSE':>10}{'ANEES':>9}{'us/step':>9}")
    for name, r in d["filters"].items():
        if "failed" in r:
            print(f"{name:<16}{failed_text(r)}")
            continue
        if "mse_x" not in r:
            print(f"{name:<16}no estimate inside the ground truth")
            continue
        print(f"{name:<16}{r['mse_x']:>10.4f}{r['mse_y']:>10.4f}{r['mse_theta']:>12.4f}"
              f"{r['pos_rmse_m']:>11.4f}{r['heading_rmse_rad']:>10.4f}{fmt(r['anees'], '.1f'):>9}"
              f"{r['us_per_step']:>9.1f}")
    if d.get("unknown_ids"):
        _print_associations(d)
    u, e = SEED_001_UKF_MSE, SEED_001_EKF_MSE
    print(f"{'seed 001 UKF':<16}{u[0]:>10.4f}{u[1]:>10.4f}{u[2]:>12.4f}   (paper, Table II)")
    print(f"{'seed 001 EKF':<16}{e[0]:>10.4f}{e[1]:>10.4f}{e[2]:>12.4f}   (paper, Table I)")


def _print_associations(d: dict[str, Any]) -> None:
    """With ``--unknown-ids``: that the filters saw no IDs, and per filter reporting
    associations, the share of readings given the landmark whose barcode was read."""
    print("unknown IDs: the filters were given every reading without its barcode and associated "
          "it themselves; the barcodes only score the associations")
    print(f"{'filter':<16}{'readings':>9}{'correct':>9}{'false':>7}{'missed':>7}{'% right':>9}")
    for name, a in d["associations"].items():
        print(f"{name:<16}{a['readings']:>9}{a['correct']:>9}{a['false']:>7}{a['missed']:>7}"
              f"{fmt(100 * a['fraction_correct'], '.1f'):>9}")
    silent = [n for n, r in d["filters"].items() if n not in d["associations"] and "failed" not in r]
    if silent:
        print(f"not scored (no associations reported): {', '.join(silent)}")


def _print_team(d: dict[str, Any]) -> None:
    """The table of a team run: per robot, each filter's position RMSE and ANEES."""
    print(f"MRCLAM {d['dataset']}, robots {', '.join(map(str, d['robots']))} together: "
          f"{d['duration_s']:.1f} s")
    for r, source in d["calibration_source"].items():
        print(f"robot {r} noise {source}")
    names = list(d["filters"])
    width = {n: max(len(n) + 9, 12) for n in names}
    head = "".join(f"{n + ' RMSE m':>{width[n]}}{'ANEES':>7}" for n in names)
    print(f"{'robot':<6}{'landmarks':>10}{'sightings':>10}{head}")
    for r in d["robots"]:
        row = "".join(f"{fmt(d['filters'][n][str(r)].get('pos_rmse_m'), '.3f'):>{width[n]}}"
                      f"{fmt(d['filters'][n][str(r)].get('anees'), '.2f'):>7}" for n in names)
        print(f"{r:<6}{d['landmark_readings'][r]:>10}{d['robot_sightings'][r]:>10}{row}")
    print("us per tick: " + ", ".join(f"{n} {v:.0f}" for n, v in d["us_per_step"].items()))
    for n, why in d.get("failed", {}).items():
        print(f"{n} switched off, no score: {why}")


def _print_slam(d: dict[str, Any]) -> None:
    """With ``--slam``: which filters were given the map, and the SLAM table."""
    from beacon_sim.evaluation.slam_run import print_mrclam_slam_table

    blind = [n for n, given in d["map_given"].items() if not given]
    kept = [n for n, given in d["map_given"].items() if given]
    print(f"SLAM: not given the landmark map: {', '.join(blind) or 'none'}"
          + (f"; given the surveyed map (the reference): {', '.join(kept)}" if kept else ""))
    print_mrclam_slam_table({n: r["slam"] for n, r in d["filters"].items()})


def _load(args: argparse.Namespace) -> list[MrclamData]:
    """The robots a command runs: ``--robot N`` alone, or (``--team``) all five with their
    sightings of each other."""
    if getattr(args, "team", False):
        if args.robot is not None:
            raise UsageError("--team runs all five robots: leave out --robot")
        return [load_mrclam(args.dir, r, robot_sightings=True) for r in ROBOT_SUBJECTS]
    if args.robot is None:
        raise UsageError("mrclam: --robot N (1 to 5) is required, or --team for all five")
    return [load_mrclam(args.dir, args.robot)]


def mrclam_command(args: argparse.Namespace) -> int:
    duration = args.duration
    check_duration(duration)
    team = getattr(args, "team", False)
    if not team:
        check_frames(args.frames)
    size = parse_size(getattr(args, "size", "1280x800"))  # a bad --size: said before the run
    slam = getattr(args, "slam", False)
    if slam and team:
        raise UsageError("--slam runs one robot: use --robot N, not --team (the team filters "
                         "are localization filters; none maps landmarks)")
    if slam and args.calibrate:
        raise UsageError("--slam runs filters; --calibrate only prints the noise: use one of them")
    try:
        robots = _load(args)
    except MrclamError as exc:
        raise UsageError(str(exc)) from None
    if args.calibrate:
        if team:
            raise UsageError("--calibrate prints one robot's noise: use --robot N, not --team")
        data = robots[0]
        t_end = None if duration is None else data.t0 + duration
        cal = calibrate(data, t_end)
        if args.json:
            print(json.dumps({"dataset": data.folder.name, "robot": data.robot,
                              "dropped": data.dropped, "step_dt": cal.step_dt,
                              "motion_noise": {"v_std": cal.motion.v_std,
                                               "omega_std": cal.motion.omega_std},
                              "sensor_noise": {"range_std": cal.sensor.range_std,
                                               "bearing_std": cal.sensor.bearing_std},
                              "stats": cal.stats}))
        else:
            _print_calibration(data, cal)
        return 0
    try:
        run = run_mrclam(robots if team else robots[0], getattr(args, "filters", None) or None,
                         duration, filter_params(args),
                         calibration=getattr(args, "calibration", None) or "others",
                         unknown_ids=getattr(args, "unknown_ids", False), slam=slam,
                         record_maps=slam and not args.headless, progress=True,
                         graph=getattr(args, "graph", False))
    except MrclamError as exc:
        raise UsageError(str(exc)) from None
    d = run.as_json()
    if slam:
        from beacon_sim.evaluation.slam_run import mrclam_slam_figures

        for name, row in mrclam_slam_figures(run).items():
            d["filters"][name]["slam"] = row
    if args.json:
        print(json.dumps(d, default=float))
    else:
        (_print_team if team else _print_run)(d)
        if slam:
            _print_slam(d)
    print_failures(t for tracks in run.robot_tracks[:1] for t in tracks.values())
    if args.headless or team:  # a team run prints its table only
        return 0
    from beacon_sim.app.mrclam import show_mrclam  # pygame only when a window opens

    return show_mrclam(run, args.frames, args.screenshot, size)
