"""``beacon-sim check FILTER [--scenario S]``: the conformance report for a filter."""

from __future__ import annotations

import argparse

from beacon_sim.core.scenario import load_scenario
from beacon_sim.filters.conformance import print_report, run_checks


def check_command(args: argparse.Namespace) -> int:
    results = run_checks(args.filter, load_scenario(args.scenario))
    print_report(args.filter, results)
    return 0 if all(r.passed for r in results) else 1
