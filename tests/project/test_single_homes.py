"""One home per idea: the bearing model lives in core/measurement_models.py and
the circular mean in core/angles.py. Where a hot path keeps a fused fast form (shared sines
and cosines, unrolled sigma points), it is held here to the one home, so the two cannot
drift apart."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from gaussian_helpers import context

from beacon_sim.core import measurement_models as mm
from beacon_sim.core.angles import circular_mean, wrap
from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.filters.base import GaussianBelief
from beacon_sim.filters.gaussian.measurements import ALL_ROWS
from beacon_sim.filters.gaussian.ukf import innovation_parts
from beacon_sim.filters.grid.histogram import HistogramFilter
from beacon_sim.filters.particle.pf import weighted_pose_stats

RNG = np.random.default_rng(22)


def test_the_bearing_model_has_one_array_and_one_scalar_form():
    dx, dy, th = RNG.normal(size=(3, 200)) * np.array([[5.0], [5.0], [3.0]])
    arr = mm.relative_bearing(dx, dy, th)
    one = np.array([mm.relative_bearing_scalar(a, b, c)
                    for a, b, c in zip(dx.tolist(), dy.tolist(), th.tolist(), strict=True)])
    np.testing.assert_allclose(arr, one, rtol=0, atol=1e-15)
    pose = np.array([1.0, -2.0, 2.5])
    bxy = np.column_stack([pose[0] + dx, pose[1] + dy])
    np.testing.assert_allclose(mm.bearing(pose, bxy), wrap(mm.relative_bearing(dx, dy, pose[2])), atol=0)
    np.testing.assert_allclose(mm.bearing_many(pose[None], bxy)[0], mm.bearing(pose, bxy), atol=0)
    # the direction is measured from the heading: a beacon straight ahead is at 0, one to
    # the left at +pi/2
    assert mm.relative_bearing_scalar(math.cos(0.3), math.sin(0.3), 0.3) == 0.0
    assert math.isclose(mm.relative_bearing_scalar(-math.sin(0.3), math.cos(0.3), 0.3), math.pi / 2)


def test_the_simulated_readings_follow_the_bearing_model():
    """What the simulation measures (noise aside) is the model: a noiseless copy of a
    bearing scenario reads exactly ``wrap(relative_bearing)`` to every beacon it sees."""
    sc = load_scenario("krejsa_bearing_only")
    quiet = [replace(s, noise=replace(s.noise, bearing_std=0.0), outlier_rate=0.0) for s in sc.sensors]
    sc = replace(sc, sensors=tuple(quiet))
    seen = 0
    for step in Simulation(sc, seed=3).run(5.0):
        for m in step.measurements:
            bxy = sc.world.beacon_xy[sc.world.beacon_index(m.beacon_ids)]
            d = bxy - step.true_pose[:2]
            np.testing.assert_allclose(m.z[:, -1], wrap(mm.relative_bearing(d[:, 0], d[:, 1],
                                                                            step.true_pose[2])), atol=1e-12)
            seen += len(m.z)
    assert seen > 20


def test_the_particle_filters_heading_mean_is_the_circular_mean():
    P = np.vstack([RNG.normal(size=(2, 500)), wrap(RNG.normal(3.0, 0.4, 500))])  # across +-pi
    w = RNG.random(500)
    w /= w.sum()
    mean, _ = weighted_pose_stats(P, w)
    assert math.isclose(mean[2], circular_mean(P[2], w), abs_tol=1e-12)


def test_the_grid_filters_heading_mean_is_the_circular_mean():
    f = HistogramFilter(context({"heading_bins": 36}))
    f.reset(GaussianBelief(np.array([0.0, 0.0, 3.0]), np.diag([0.5, 0.5, 0.6]) ** 2))
    mean, _ = f.estimate()
    per_bin = f.grid.sum(axis=(1, 2))
    assert math.isclose(mean[2], circular_mean(f.theta, per_bin), abs_tol=1e-12)


def test_the_ukfs_expected_bearing_is_the_circular_mean():
    Z = wrap(RNG.normal(3.1, 0.3, size=(7, 4)))          # sigma-point bearings across +-pi
    D = RNG.normal(size=(7, 3))
    z = wrap(RNG.normal(3.1, 0.3, size=4))
    Wm = np.array([0.4] + [0.1] * 6)
    _, _, _, nu = innovation_parts(Z, D, z, ALL_ROWS, Wm, Wm.copy())
    np.testing.assert_allclose(nu, wrap(z - circular_mean(Z, Wm[:, None], axis=0)), atol=1e-12)
