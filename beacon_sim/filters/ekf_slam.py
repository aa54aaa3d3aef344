"""The old import path of EKF-SLAM, which now lives in
:mod:`beacon_sim.filters.slam.ekf_slam` (the SLAM family, docs/architecture.md).

Files written against ``beacon_sim.filters.ekf_slam`` keep working: this module only re-exports
the public names of its new home. New code imports from there."""

from beacon_sim.filters.slam.ekf_slam import *  # noqa: F403 (the old path re-exports its new home's public names)
from beacon_sim.filters.slam.ekf_slam import __all__ as __all__
