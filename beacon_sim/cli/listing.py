"""``beacon-sim list``: the shipped scenarios and the available filters."""

from __future__ import annotations

import argparse

from beacon_sim.core.resources import shipped_scenarios
from beacon_sim.core.scenario import load_scenario
from beacon_sim.filters.loading import available_filters


def list_command(args: argparse.Namespace) -> int:
    print("scenarios:")
    for name in shipped_scenarios():
        print(f"  {name:<22}{load_scenario(name).description}")
    print("filters:")
    for name in available_filters():
        print(f"  {name}")
    return 0
