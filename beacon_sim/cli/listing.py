"""``beacon-sim list``: the shipped scenarios, each described in full sentences, the team
scenarios (several robots, docs/multi-robot.md), and the available filters and team
filters."""

from __future__ import annotations

import argparse
import shutil
import textwrap

from beacon_sim.core.resources import shipped_scenarios
from beacon_sim.core.scenario import (
    Scenario,
    TeamScenario,
    load_scenario,
    load_team_scenario,
    shipped_team_scenarios,
)
from beacon_sim.filters.team import TEAM_FILTERS
from beacon_sim.hosting.loading import available_filters

#: Left margin of a scenario's description [characters].
INDENT = 6


def describe(scenario: Scenario | TeamScenario, width: int) -> list[str]:
    """The lines ``list`` prints for one scenario: its name, then its whole description and
    what it runs (length, robots, default filters), wrapped at ``width`` characters, never cut."""
    robots = ""
    if isinstance(scenario, TeamScenario):
        robots = f"robots {', '.join(r.name for r in scenario.robots)} (Tab switches the driven one); "
    facts = (f"{scenario.duration:g} s long; {robots}the window opens with "
             f"{', '.join(scenario.default_filters) or 'no filter'}.")
    text = " ".join((scenario.description or "(no description)").split())
    wrap = textwrap.TextWrapper(width=max(width, INDENT + 30), initial_indent=" " * INDENT,
                                subsequent_indent=" " * INDENT, break_long_words=False,
                                break_on_hyphens=False)
    return [f"  {scenario.name}", *wrap.wrap(text), *wrap.wrap(facts)]


def list_command(args: argparse.Namespace) -> int:
    width = min(shutil.get_terminal_size((88, 24)).columns, 100) - 1
    print("scenarios:")
    for name in shipped_scenarios():
        print("\n".join(describe(load_scenario(name), width)))
    print("team scenarios (several robots):")
    for name in shipped_team_scenarios():
        print("\n".join(describe(load_team_scenario(name), width)))
    print("filters:")
    for name in available_filters():
        print(f"  {name}")
    print("team filters:")
    for name in TEAM_FILTERS:
        print(f"  {name}")
    print("  independent:F (filter F on every robot)")
    return 0
