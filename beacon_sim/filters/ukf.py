"""The old import path of the unscented Kalman filter, which now lives in
:mod:`beacon_sim.filters.gaussian.ukf` (the Gaussian family, docs/architecture.md).

Files written against ``beacon_sim.filters.ukf`` keep working: this module only re-exports
the public names of its new home. New code imports from there."""

from beacon_sim.filters.gaussian.ukf import (
    MAX_HEADING_OFFSET,
    BatchedUKF,
    UnscentedKalmanFilter,
    cholesky3,
    correct,
    correct_low_rank,
    heading_limited_weights,
    innovation,
    innovation_parts,
    robust_sqrt,
    sigma_weights,
    unscented_gate,
)

__all__ = [
    "MAX_HEADING_OFFSET", "BatchedUKF", "UnscentedKalmanFilter", "cholesky3", "correct",
    "correct_low_rank", "heading_limited_weights", "innovation", "innovation_parts", "robust_sqrt",
    "sigma_weights", "unscented_gate",
]
