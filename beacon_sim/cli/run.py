"""``beacon-sim run SCENARIO [--filter F ...] [--seed N] [--duration S] [--json]``: one
headless run, its summary printed."""

from __future__ import annotations

import argparse
import json
import sys

from beacon_sim.cli.common import (
    check_duration,
    check_set_names,
    filter_params,
    print_failures,
    print_sensor_notes,
)
from beacon_sim.cli.tables import print_run
from beacon_sim.core.scenario import load_scenario
from beacon_sim.runs.headless import run_headless


def run_command(args: argparse.Namespace) -> int:
    scenario = load_scenario(args.scenario)
    check_duration(args.duration, scenario)
    check_set_names(args, list(args.filters or scenario.default_filters))
    result = run_headless(scenario, args.filters, seed=args.seed, duration=args.duration,
                          params=filter_params(args), progress=sys.stderr.isatty())
    print_sensor_notes(list(args.filters or scenario.default_filters), scenario)
    data = result.as_json()
    if args.json:
        print(json.dumps(data, indent=None, default=float))
    else:
        print_run(data)
    print_failures(result.runner.tracks.values())
    return 0
