"""What the commands a user gives during a run do (kidnap, reset, ...), applied the same
way live and on replay, so that a recording reproduces the session bit for bit.

The commands themselves (small JSON-ready dicts) are defined with the recording format,
:data:`beacon_sim.io.recording.COMMAND_KINDS`:
- ``kidnap`` with a ``pose``: teleport the robot there; without: to a random pose drawn from
  the events stream;
- ``reset``: every filter back to the scenario's initial belief;
- ``global_reset``: filters that support it get a uniform belief;
- ``toggle``: show / hide a filter (display only: nothing here).
Commands are applied before the simulation step of the tick they are recorded with.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

from beacon_sim.core.scenario import Scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.filters.base import Filter
from beacon_sim.filters.loading import reset_filter
from beacon_sim.io.recording import validate_command


def apply_commands(commands: Iterable[Mapping], sim: Simulation, filters: Mapping[str, Filter],
                   scenario: Scenario) -> None:
    """Apply user commands to the simulation and the filters (``name -> filter``)."""
    commands = list(commands)
    for cmd in commands:
        validate_command(cmd)
        if cmd["kind"] == "kidnap":
            sim.request_kidnap(cmd.get("pose"))
    apply_to_filters(commands, filters, scenario)


def apply_to_filters(commands: Iterable[Mapping], filters: Mapping[str, Filter],
                     scenario: Scenario) -> None:
    """The filters' part of user commands (resets), also for a filter that catches up over a
    session's history after a hot reload."""
    for cmd in commands:
        kind = cmd["kind"]
        if kind == "reset":
            for f in filters.values():
                reset_filter(f, scenario)
        elif kind == "global_reset":
            for f in filters.values():
                if getattr(f, "supports_global", False):
                    f.reset(None)
