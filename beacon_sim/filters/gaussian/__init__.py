"""The Gaussian family: filters whose belief is one Gaussian over the pose ``[x, y, theta]``.

Read in this order:

- ``kf.py``: the linear Kalman filter of the classroom assignment (pose fixes);
- ``ekf.py``: the extended Kalman filter (any beacon reading, linearised at the mean), and the
  velocity-model prediction the others reuse;
- ``ukf.py``: the unscented Kalman filter (sigma points instead of Jacobians), its transform
  in ``unscented.py``;
- ``dead_reckoning.py``: prediction only, the baseline;
- ``measurements/``: what they share, for one run or R runs at once (the readings of a tick
  stacked into one update, their noise, gates and NIS).

Each filter also has a batched form (R runs as arrays) for Monte Carlo evaluation, held to
the one-run form by tests. The family imports the shared home (``filters/base.py``,
``filters/association/``, ``filters/params.py``) and the core, never another family
(an import-linter contract in pyproject.toml).
"""
