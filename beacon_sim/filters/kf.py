"""The old import path of the linear Kalman filter, which now lives in
:mod:`beacon_sim.filters.gaussian.kf` (the Gaussian family, docs/architecture.md).

Files written against ``beacon_sim.filters.kf`` keep working: this module only re-exports
the public names of its new home. New code imports from there."""

from beacon_sim.filters.gaussian.kf import *  # noqa: F403 (the old path re-exports its new home's public names)
from beacon_sim.filters.gaussian.kf import __all__ as __all__
