"""The old import path of the filter runner, which now lives in
:mod:`beacon_sim.hosting.runner` (the hosting layer: running someone's filter,
docs/architecture.md).

Files written against ``beacon_sim.filters.runner`` keep working: this module only re-exports
the public names of its new home. New code imports from there."""

from beacon_sim.hosting.runner import *  # noqa: F403 (the old path re-exports its new home's public names)
from beacon_sim.hosting.runner import __all__ as __all__
