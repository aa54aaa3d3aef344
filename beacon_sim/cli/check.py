"""``beacon-sim check FILTER [--scenario S]``: the conformance report for a filter."""

from __future__ import annotations

import argparse

from beacon_sim.core.scenario import load_scenario
from beacon_sim.filters.conformance import print_report, run_checks
from beacon_sim.filters.loading import load_filter_class


def check_command(args: argparse.Namespace) -> int:
    """The report; exit status 0 when every check passes, 1 when one fails, 2 (one line)
    when the name is not a filter at all (unknown name, missing file or class)."""
    scenario = load_scenario(args.scenario)
    load_filter_class(args.filter)  # FilterLoadError: one line, exit status 2
    results = run_checks(args.filter, scenario)
    print_report(args.filter, results)
    return 0 if all(r.passed for r in results) else 1
