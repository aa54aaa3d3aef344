"""Data association: which beacon of a known map each reading without an ID came from.

Unknown correspondence (seed 003: "doors in a corridor look alike"): a beacon sensor reports
bearings ``[b]`` or range-bearings ``[r, b]`` (rows of ``z``, shape (m, d), d = 1 or 2, in the
robot frame, [m, rad]) but not which beacon each row belongs to. This module answers that for
a Gaussian pose belief (mean (3,), covariance P (3, 3) [m, m, rad]) and for a particle set
(poses (N, 3)). Beacons are given as positions ``beacon_xy`` (n, 2) [m] in the world frame and
their ``beacon_ids`` (n,).

- :func:`linearise`: every reading against every beacon: the innovation ``nu_ij = z_i - h_j``
  (bearing residual wrapped to [-pi, pi)), ``H_j`` (d, 3), ``S_j = H_j P H_j^T + R`` and the
  squared Mahalanobis distance ``d2_ij = nu_ij^T S_j^-1 nu_ij``.
- :func:`gate`: the chi-square quantile a distance must not exceed (``prob`` of the true
  pairings pass, with d degrees of freedom).
- :func:`nearest_neighbour`: greedy nearest neighbour inside the gate.
- :func:`jcbb`: joint compatibility branch and bound (Neira and Tardos 2001), with a node cap
  and a fallback to nearest neighbour; its search, :func:`jcbb_search`, is the one JCBB of
  the package (EKF-SLAM's full state and FastSLAM's particles call it with their own
  joint test; :func:`linearised_landmarks` is a particle's linearisation).
- :func:`joint_nis`: the joint NIS of a pairing, with the cross terms the shared pose error
  induces between readings.
- :func:`particle_ml_association`: per particle and reading, the most likely beacon and its
  log-likelihood, vectorised over particles (for the particle filter).

The result of the Gaussian methods is an :class:`Association`: for each reading, the ID of the
beacon it was given to, or None (clutter, or no beacon compatible with it).

The filters' hooks (each filter calls one at the start of its update and
returns at once when every sensor tells its IDs): :func:`associate_gaussian` (EKF, UKF: NN or
JCBB at the predicted belief, then a labeled reading), :func:`particle_loglik` (per-particle
maximum likelihood), :func:`grid_mixture` (the histogram's mixture over the beacons). What
they chose is reported by ``FilterBase.associations()``.
"""


from __future__ import annotations

from beacon_sim.filters.association.hooks import (
    GAUSSIAN_PARAMS,
    METHODS,
    MIN_CLUTTER_SHARE,
    associate_gaussian,
    attach,
    grid_mixture,
    inflated,
    is_unlabeled,
    particle_loglik,
    particle_start,
    refuse_ambiguous,
)
from beacon_sim.filters.association.jcbb import (
    MAX_NODES,
    JointInformation,
    JointTest,
    information_sums,
    jcbb,
    jcbb_search,
)
from beacon_sim.filters.association.linearised import (
    GATE_PROB,
    READING_DIMS,
    Association,
    Linearised,
    Pairing,
    check_readings,
    expected,
    gate,
    joint_nis,
    linearise,
    linearised_landmarks,
    residual,
)
from beacon_sim.filters.association.nearest_neighbour import (
    check_ids,
    nearest_neighbour,
    nn_pairing,
    to_association,
)
from beacon_sim.filters.association.per_particle import (
    particle_d2,
    particle_ml_association,
)

__all__ = [
    "GATE_PROB", "GAUSSIAN_PARAMS", "MAX_NODES", "METHODS", "MIN_CLUTTER_SHARE", "READING_DIMS",
    "Association", "JointInformation", "JointTest", "Linearised", "Pairing", "associate_gaussian",
    "attach", "check_ids", "check_readings", "expected", "gate", "grid_mixture", "inflated",
    "information_sums", "is_unlabeled", "jcbb", "jcbb_search", "joint_nis", "linearise",
    "linearised_landmarks", "nearest_neighbour", "nn_pairing", "particle_d2", "particle_loglik",
    "particle_ml_association", "particle_start", "refuse_ambiguous", "residual", "to_association",
]
