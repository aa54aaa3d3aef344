"""The old import path of hot reload, which now lives in
:mod:`beacon_sim.hosting.hot_reload` (the hosting layer: running someone's filter,
docs/architecture.md).

Files written against ``beacon_sim.filters.hot_reload`` keep working: this module only re-exports
the public names of its new home. New code imports from there."""

from beacon_sim.hosting.hot_reload import *  # noqa: F403 (the old path re-exports its new home's public names)
from beacon_sim.hosting.hot_reload import __all__ as __all__
