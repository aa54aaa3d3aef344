"""Commands a user gives during a run (kidnap, reset, ...), applied the same way live and
on replay, so that a recording reproduces the session bit for bit.

A command is a small JSON-ready dict:
- ``{"kind": "kidnap", "pose": [x, y, theta]}``: teleport the robot there (mouse click);
- ``{"kind": "kidnap"}``: teleport to a random pose from the events stream (K key);
- ``{"kind": "reset"}``: every filter back to the scenario's initial belief (R key);
- ``{"kind": "global_reset"}``: filters that support it get a uniform belief (G key);
- ``{"kind": "toggle", "filter": NAME}``: show / hide a filter (display only).
Commands are applied before the simulation step of the tick they are recorded with.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

from beacon_sim.core.scenario import Scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.filters.loading import reset_filter

COMMAND_KINDS = ("kidnap", "reset", "global_reset", "toggle")


def validate_command(cmd: Mapping) -> None:
    """Raise ValueError for a command this version does not know."""
    kind = cmd.get("kind")
    if kind not in COMMAND_KINDS:
        raise ValueError(f"unknown user command {kind!r}; expected one of {COMMAND_KINDS}")
    if kind == "kidnap" and "pose" in cmd and len(cmd["pose"]) != 3:
        raise ValueError(f"kidnap pose {cmd['pose']!r}: expected [x, y, theta]")


def apply_commands(commands: Iterable[Mapping], sim: Simulation, filters: Mapping[str, object],
                   scenario: Scenario) -> None:
    """Apply user commands to the simulation and the filters (``name -> filter``)."""
    for cmd in commands:
        validate_command(cmd)
        kind = cmd["kind"]
        if kind == "kidnap":
            sim.request_kidnap(cmd.get("pose"))
        elif kind == "reset":
            for f in filters.values():
                reset_filter(f, scenario)
        elif kind == "global_reset":
            for f in filters.values():
                if getattr(f, "supports_global", False):
                    f.reset(None)
