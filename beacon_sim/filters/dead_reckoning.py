"""The old import path of dead reckoning, which now lives in
:mod:`beacon_sim.filters.gaussian.dead_reckoning` (the Gaussian family, docs/architecture.md).

Files written against ``beacon_sim.filters.dead_reckoning`` keep working: this module only re-exports
the public names of its new home. New code imports from there."""

from beacon_sim.filters.gaussian.dead_reckoning import *  # noqa: F403 (the old path re-exports its new home's public names)
from beacon_sim.filters.gaussian.dead_reckoning import __all__ as __all__
