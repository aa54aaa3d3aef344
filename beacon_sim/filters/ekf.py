"""The old import path of the extended Kalman filter, which now lives in
:mod:`beacon_sim.filters.gaussian.ekf` (the Gaussian family, docs/architecture.md).

Files written against ``beacon_sim.filters.ekf`` keep working: this module only re-exports
the public names of its new home. New code imports from there."""

from beacon_sim.filters.gaussian.ekf import *  # noqa: F403 (the old path re-exports its new home's public names)
from beacon_sim.filters.gaussian.ekf import __all__ as __all__
