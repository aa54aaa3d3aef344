"""The old import path of scan-based Monte Carlo localization, which now lives in
:mod:`beacon_sim.filters.particle.mcl` (the particle family, docs/architecture.md).

Files written against ``beacon_sim.filters.mcl`` keep working: this module only re-exports
the public names of its new home. New code imports from there."""

from beacon_sim.filters.particle.mcl import *  # noqa: F403 (the old path re-exports its new home's public names)
from beacon_sim.filters.particle.mcl import __all__ as __all__
