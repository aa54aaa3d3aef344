"""The old import path of seed 004's corridor filter, which now lives in
:mod:`beacon_sim.filters.grid.corridor` (the grid family, docs/architecture.md).

Files written against ``beacon_sim.filters.corridor`` keep working: this module only re-exports
the public names of its new home. New code imports from there."""

from beacon_sim.filters.grid.corridor import Corridor, CorridorFilter, walls_seen

__all__ = ["Corridor", "CorridorFilter", "walls_seen"]
