"""Bayesian filters on top of the core: the interface, the built-in filters, loading.

The algorithms a student reads stand in four families, each a package that reads alone
(docs/architecture.md, "filters/"): ``gaussian/`` (kf, ekf, ukf, dead reckoning),
``particle/`` (pf, mcl), ``grid/`` (histogram, corridor) and ``slam/`` (ekf_slam, fastslam).
A family imports the shared home beside it (``base``, ``registry``, ``params``,
``param_ranges``, ``association``, ``resampling``) and the core, never another family.

Filters never import pygame and never see the true pose.
"""

#: The old import path of each module that moved into a family -> its new home. Each old
#: path is a short module that re-exports the new one's public names, so files written
#: before the families (a student's ``from beacon_sim.filters.ekf import
#: ExtendedKalmanFilter``) keep working; ``beacon_sim.filters.particle`` is now the particle
#: family's package and re-exports the particle filter's names itself.
MOVED = {
    "beacon_sim.filters.kf": "beacon_sim.filters.gaussian.kf",
    "beacon_sim.filters.ekf": "beacon_sim.filters.gaussian.ekf",
    "beacon_sim.filters.ukf": "beacon_sim.filters.gaussian.ukf",
    "beacon_sim.filters.dead_reckoning": "beacon_sim.filters.gaussian.dead_reckoning",
    "beacon_sim.filters.particle": "beacon_sim.filters.particle.pf",
    "beacon_sim.filters.mcl": "beacon_sim.filters.particle.mcl",
    "beacon_sim.filters.histogram": "beacon_sim.filters.grid.histogram",
    "beacon_sim.filters.corridor": "beacon_sim.filters.grid.corridor",
    "beacon_sim.filters.ekf_slam": "beacon_sim.filters.slam.ekf_slam",
    "beacon_sim.filters.fastslam": "beacon_sim.filters.slam.fastslam",
}

#: The old import path of each module that moved into the hosting layer (running someone's
#: filter, ``beacon_sim.hosting``) and that the docs once named -> its new home; each is a
#: short module that re-exports the new one's public names.
HOSTED = {
    "beacon_sim.filters.runner": "beacon_sim.hosting.runner",
    "beacon_sim.filters.hot_reload": "beacon_sim.hosting.hot_reload",
}
