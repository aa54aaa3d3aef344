"""The SLAM family: filters that are not given the beacon map and estimate it with the pose
(docs/slam.md). A SLAM filter adds ``landmarks()`` (and ``joint()``) to the interface.

- ``base.py``: what they share: the landmark observation model and its Jacobians, the
  placing of a new landmark, and a base class that sorts a tick's readings;
- ``ekf_slam.py``: EKF-SLAM, one Gaussian over the pose and every landmark
  (``--filter ekf_slam``);
- ``inverse_depth.py``: inverse-depth landmarks, EKF-SLAM's bearing-only initialisation;
- ``fastslam.py``: FastSLAM 2.0, particles over the path, each with its own landmark EKFs
  (``--filter fastslam``); with ``fastslam_proposal.py`` (a reading folded into each
  particle's pose proposal, and its weight), ``particle_association.py`` (which landmark each
  particle pairs each reading with: ML, JCBB, the known-ID gate) and
  ``linearised_covariance.py`` (the EKF-SLAM covariance it reports).

They import the shared home (``filters/base.py``, ``filters/association/``,
``filters/resampling.py``) and the core, never another family (an import-linter contract in
pyproject.toml).
"""
