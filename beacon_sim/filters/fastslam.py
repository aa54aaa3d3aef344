"""The old import path of FastSLAM 2.0, which now lives in
:mod:`beacon_sim.filters.slam.fastslam` (the SLAM family, docs/architecture.md).

Files written against ``beacon_sim.filters.fastslam`` keep working: this module only re-exports
the public names of its new home. New code imports from there."""

from beacon_sim.filters.slam.fastslam import *  # noqa: F403 (the old path re-exports its new home's public names)
from beacon_sim.filters.slam.fastslam import __all__ as __all__
