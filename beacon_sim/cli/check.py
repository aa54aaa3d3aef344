"""``beacon-sim check FILTER [--scenario S]``: the conformance report for a filter."""

from __future__ import annotations

import argparse

from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.team_scenario import is_team_scenario, load_team_scenario
from beacon_sim.filters.conformance import print_report, run_checks
from beacon_sim.filters.loading import load_filter_class
from beacon_sim.runs.team_conformance import run_team_checks


def check_command(args: argparse.Namespace) -> int:
    """The report; exit status 0 when every check passes, 1 when one fails, 2 (one line)
    when the name is not a filter at all (unknown name, missing file or class). A team
    filter class (one with ``estimates()``) is checked on a team scenario (default
    ``team_sparse``)."""
    cls = load_filter_class(args.filter)  # FilterLoadError: one line, exit status 2
    if callable(getattr(cls, "estimates", None)) and not callable(getattr(cls, "estimate", None)):
        name = args.scenario if is_team_scenario(args.scenario) else "team_sparse"
        results = run_team_checks(args.filter, cls, load_team_scenario(name))
        print_report(args.filter, results)
        return 0 if all(r.passed for r in results) else 1
    scenario = load_scenario(args.scenario)
    results = run_checks(args.filter, scenario)
    print_report(args.filter, results)
    return 0 if all(r.passed for r in results) else 1
