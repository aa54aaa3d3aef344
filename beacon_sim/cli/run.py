"""``beacon-sim run SCENARIO [--filter F ...] [--seed N] [--duration S] [--json]``: one
headless run, its summary printed. A team scenario (``[[robots]]``, docs/multi-robot.md)
runs team filters (``--filter independent``, ``centralised``, ``ci``, ``naive`` or
``independent:F``) and prints a row per robot and the team's."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from beacon_sim.cli.common import (
    check_duration,
    check_set_names,
    filter_params,
    print_failures,
    print_sensor_notes,
)
from beacon_sim.cli.tables import failed_text, fmt, print_run
from beacon_sim.core.scenario import load_any_scenario
from beacon_sim.errors import UsageError
from beacon_sim.evaluation.association_metrics import association_report
from beacon_sim.evaluation.slam_run import print_slam_table, slam_figures
from beacon_sim.evaluation.smoothing_run import run_figures
from beacon_sim.evaluation.smoothing_run import table_lines as smoothing_lines
from beacon_sim.hosting.team_specs import check_team_specs
from beacon_sim.runs.headless import run_headless


def run_command(args: argparse.Namespace) -> int:
    """One run over the scenario's robots (a single-robot file: a team of one); the filter
    specs are checked first (a bad name or ``--set``: one line, exit status 2)."""
    team = load_any_scenario(args.scenario)
    check_duration(args.duration, team.robots[0].scenario)
    specs = list(args.filters or team.default_filters)
    if team.solo:  # single-robot filter specs
        check_set_names(args, specs)
        params = filter_params(args)
    else:  # team filter specs (hosting/team_specs.py)
        params = filter_params(args)
        check_team_specs(specs, team, params)
    result = run_headless(team, specs, seed=args.seed, duration=args.duration, params=params,
                          progress=True, on_slow=lambda line: print(line, file=sys.stderr))
    if team.solo:
        print_sensor_notes(specs, team.robots[0].scenario)
    data = result.as_json()
    slam = slam_figures(result)  # each SLAM filter's ATE, map GOSPA, joint NEES
    for name, fig in slam.items():
        data["filters"][name]["slam"] = fig
    smoothed = None
    if getattr(args, "smooth", False):  # EKF/UKF runs smoothed (docs/smoothing.md)
        if not team.solo:
            raise UsageError("run --smooth: single-robot scenarios only")
        smoothed = run_figures(team.robots[0].scenario, specs, result.seed, result.steps, params)
        for name, fig in smoothed.items():
            data["filters"][name]["smoothing"] = fig
        if not smoothed:
            print("note: --smooth: no filter of this run can be smoothed (ekf, ukf)", file=sys.stderr)
    scored = None
    if getattr(args, "associations", False) and team.solo:  # a second run, IDs told
        scored = association_report(team.robots[0].scenario, args.filters, args.seed,
                                    args.duration, params)
        data["associations"] = scored.json
    if args.json:
        print(json.dumps(data, indent=None, default=float))
    elif team.solo:
        print_run(data)
        print_slam_table(slam)
        if smoothed:
            print("\n".join(smoothing_lines(smoothed)))
    else:
        print_team_run(data)
    print_failures(result.tracks.values())
    if scored is not None and not args.json:
        print(scored.text)
    return 0


def print_team_run(d: dict[str, Any]) -> None:
    """The summary of one headless team run (``RunResult.as_json()`` of a team)."""
    print(f"team scenario {d['scenario']}  seed {d['seed']}  steps {d['steps']} "
          f"({d['sim_time_s']:g} s simulated)  robots {', '.join(d['robots'])}")
    reads = ", ".join(f"{rn}: {v['beacon']} beacon / {v['robot']} robot" for rn, v in d["readings"].items())
    print(f"readings      {reads}")
    print(f"truth checksum {d['truth_checksum']}")
    lo, hi = d["anees_band"]
    tlo, thi = d["team_anees_band"]
    print(f"{'filter':<16}{'robot':<12}{'pos RMSE m':>11}{'head RMSE':>11}{'ANEES':>9} {'verdict':<12}"
          f"{'us/step':>9}")
    for name, r in d["filters"].items():
        if "failed" in r:
            print(f"{name:<16}{failed_text(r)} (no score)")
            continue
        if not r["robots"]:
            print(f"{name:<16}no estimate (no steps)")
            continue
        for k, (rn, v) in enumerate(r["robots"].items()):
            print(f"{name if k == 0 else '':<16}{rn:<12}{v['pos_rmse_m']:>11.4f}"
                  f"{v['heading_rmse_rad']:>11.4f}{fmt(v['anees'], '.2f'):>9} {v['anees_verdict']:<12}")
        print(f"{'':<16}{'team':<12}{r['team_pos_rmse_m']:>11.4f}{r['team_heading_rmse_rad']:>11.4f}"
              f"{fmt(r['team_anees'], '.2f'):>9} {r['team_anees_verdict']:<12}{r['us_per_step']:>9.1f}")
    print(f"ANEES 95 % band of one run: [{lo:.2f}, {hi:.2f}] per robot, [{tlo:.2f}, {thi:.2f}] for the "
          f"team of {len(d['robots'])} (3 dof)")
