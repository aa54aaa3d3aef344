"""The particle family: filters whose belief is a weighted set of poses.

- ``pf.py``: the particle filter for any sensor kind (``--filter pf``): Monte Carlo
  localization; with ``recovery.py`` (the lost test and augmented MCL's recovery from
  kidnaps), ``regularise.py`` (kernel jitter, progressive correction) and
  ``adaptive_count.py`` (KLD-sampling, seed 002's count);
- ``mcl.py``: Monte Carlo localization on an occupancy grid's laser scans (``--filter mcl``,
  ROS amcl's ideas and parameter names);
- what ``pf.py`` uses beside its algorithm: ``pose_stats.py`` (the weighted mean and
  covariance of the particles, the dominant mode), ``log_weights.py`` (log-sum-exp and the
  effective sample size), ``fast_calls.py`` (numpy calls without their Python layers, for the
  hot path).

How a reading is weighed at the particles is its sensor kind's, not the family's: the kind's
model in the core (``particle_fit``, core/particle_likelihood.py), which any particle filter
composes. The resampling schemes they use are shared (``filters/resampling.py``: FastSLAM
resamples too), as are the interface (``filters/base.py``) and data association
(``filters/association/``). The family never imports another family (an import-linter
contract in pyproject.toml).

``beacon_sim.filters.particle`` was the particle filter's own module before the families:
its public names are re-exported here, so ``from beacon_sim.filters.particle import
ParticleFilter`` keeps working. New code imports from ``beacon_sim.filters.particle.pf``.
"""

from beacon_sim.filters.particle.pf import COLLAPSE_ESS, LOST_AT, TWO_PI, ParticleFilter, weighted_pose_stats

__all__ = ["COLLAPSE_ESS", "LOST_AT", "TWO_PI", "ParticleFilter", "weighted_pose_stats"]
