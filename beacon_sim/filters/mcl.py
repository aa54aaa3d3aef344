"""The old import path of scan-based Monte Carlo localization, which now lives in
:mod:`beacon_sim.filters.particle.mcl` (the particle family, docs/architecture.md).

Files written against ``beacon_sim.filters.mcl`` keep working: this module only re-exports
the public names of its new home. New code imports from there."""

from beacon_sim.filters.particle.mcl import (
    LASER_MODELS,
    MOTION_TRIES,
    ROUGHENING_FLOOR,
    MonteCarloLocalization,
    kld_bound,
    open_grid,
    subsample_beams,
)

__all__ = [
    "LASER_MODELS", "MOTION_TRIES", "ROUGHENING_FLOOR", "MonteCarloLocalization", "kld_bound", "open_grid",
    "subsample_beams",
]
