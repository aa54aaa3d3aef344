"""The old import path of seed 004's corridor filter, which now lives in
:mod:`beacon_sim.filters.grid.corridor` (the grid family, docs/architecture.md).

Files written against ``beacon_sim.filters.corridor`` keep working: this module only re-exports
the public names of its new home. New code imports from there."""

from beacon_sim.filters.grid.corridor import *  # noqa: F403 (the old path re-exports its new home's public names)
from beacon_sim.filters.grid.corridor import __all__ as __all__
