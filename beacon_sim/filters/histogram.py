"""The old import path of the histogram (grid Bayes) filter, which now lives in
:mod:`beacon_sim.filters.grid.histogram` (the grid family, docs/architecture.md).

Files written against ``beacon_sim.filters.histogram`` keep working: this module only re-exports
the public names of its new home. New code imports from there."""

from beacon_sim.filters.grid.histogram import *  # noqa: F403 (the old path re-exports its new home's public names)
from beacon_sim.filters.grid.histogram import __all__ as __all__
