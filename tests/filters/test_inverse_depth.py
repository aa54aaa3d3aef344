"""Inverse-depth initialisation for bearing-only EKF-SLAM (``bearing_init = "inverse_depth"``)
against the maths: the bearing model of an inverse-depth landmark and its Jacobians, the
conversion to Euclidean and its Jacobian, both against finite differences; the conversion
inside the filter is the linearised transform of the mean and covariance; and a seeded Monte
Carlo on the shipped bearing-only scenario: joint ANEES in its band, map error as good as the
delayed initialisation's."""

from __future__ import annotations

import math

import numpy as np
import pytest
from slam_helpers import ring_scenario, run, true_beacons

from beacon_sim.core.angles import wrap
from beacon_sim.core.resources import shipped_scenarios
from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.types import Measurement
from beacon_sim.evaluation.slam_metrics import joint_anees_band, joint_nees
from beacon_sim.filters.base import FilterError
from beacon_sim.filters.slam import inverse_depth as idp
from beacon_sim.filters.slam.base import observe
from beacon_sim.filters.slam.ekf_slam import EKFSLAM
from beacon_sim.hosting.loading import build_filter

POSES = [np.array([1.0, 2.0, 0.3]), np.array([-1.0, 0.5, 3.1]), np.array([2.0, -3.0, -3.1])]
FEATURES = [np.array([0.0, 0.0, 0.9, 0.25]), np.array([-3.0, 1.0, 2.8, 0.6]),
            np.array([4.0, -1.0, -1.2, 0.0]),    # at infinity
            np.array([1.0, 1.0, 0.2, -0.05])]    # a little past infinity (the prior allows it)


def central(f, x, eps=1e-6, wrap_last=True):
    cols = []
    for j in range(x.size):
        dx = np.zeros(x.size)
        dx[j] = eps
        d = np.atleast_1d(np.asarray(f(x + dx), dtype=float) - np.asarray(f(x - dx), dtype=float))
        if wrap_last:
            d[-1] = wrap(d[-1])
        cols.append(d / (2 * eps))
    return np.stack(cols, axis=1)


@pytest.mark.parametrize("i", range(3))
@pytest.mark.parametrize("k", range(4))
def test_the_inverse_depth_bearing_jacobians_match_finite_differences(i, k):
    pose, y = POSES[i], FEATURES[k]
    _, Hx, Hy = idp.observe(pose, y)
    assert np.allclose(Hx, central(lambda p: idp.observe(p, y)[0], pose)[0], atol=1e-6)
    assert np.allclose(Hy, central(lambda v: idp.observe(pose, v)[0], y)[0], atol=1e-6)


@pytest.mark.parametrize("i", range(3))
@pytest.mark.parametrize("k", [0, 1])
def test_the_inverse_depth_bearing_is_the_bearing_of_its_point(i, k):
    pose, y = POSES[i], FEATURES[k]
    m, _ = idp.to_xy(y)
    assert idp.observe(pose, y)[0] == pytest.approx(float(observe("bearing", pose, m)[0][0, 0]), abs=1e-12)


@pytest.mark.parametrize("k", [0, 1, 3])
def test_the_conversion_and_its_jacobian_match_finite_differences(k):
    y = FEATURES[k]
    m, J = idp.to_xy(y)
    assert np.allclose(m, y[:2] + np.array([math.cos(y[2]), math.sin(y[2])]) / y[3])
    assert np.allclose(J, central(lambda v: idp.to_xy(v)[0], y, wrap_last=False), atol=1e-5)


def test_initialisation_puts_the_ray_in_the_world_and_its_jacobians_match():
    pose, b = POSES[1], 0.4
    y, Gx, Gz = idp.initialise(pose, b, 0.25)
    assert np.allclose(y, [pose[0], pose[1], wrap(pose[2] + b), 0.25])
    assert np.allclose(Gx, central(lambda p: idp.initialise(p, b, 0.25)[0], pose, wrap_last=False), atol=1e-6)
    assert np.allclose(Gz, central(lambda z: idp.initialise(pose, z[0], 0.25)[0], np.array([b]),
                                   wrap_last=False)[:, 0], atol=1e-6)
    # the bearing it would read from the same pose is the one it was started from
    assert idp.observe(pose, y)[0] == pytest.approx(b, abs=1e-12)


def test_the_linearity_index_falls_with_parallax_and_is_infinite_at_infinity():
    y = np.array([0.0, 0.0, 0.0, 0.2])            # 5 m ahead along +x
    along = idp.linearity_index(y, 0.05 ** 2, np.array([0.0, 0.0]))
    across = idp.linearity_index(y, 0.05 ** 2, np.array([5.0, -3.0]))
    assert along == pytest.approx(4 * 0.05 / 0.2 ** 2 / 5.0)
    assert across < 1e-9 < along  # seen at right angles to the ray: no depth in the bearing
    assert idp.linearity_index(np.array([0.0, 0.0, 0.0, 0.0]), 0.01, np.zeros(2)) == math.inf


def _filter():
    sc = ring_scenario(5, duration=5.0, bearing_only=True, anchors=(1, 2))
    f = build_filter("ekf_slam", sc, 0, params={"bearing_init": "inverse_depth"})
    assert isinstance(f, EKFSLAM)
    return f


def test_a_first_bearing_enters_the_state_in_inverse_depth_with_the_poses_cross_terms():
    f = _filter()
    f.P = np.diag([0.01, 0.02, 0.003])
    f.update([Measurement("beacons", "bearing", np.array([[0.5]]), np.array([3]))])
    assert f.idp == [3] and f.ids == [] and f.mu.size == 7
    assert np.allclose(f.mu[3:], [f.mu[0], f.mu[1], f.mu[2] + 0.5, 0.25])
    Gx = idp.initialise(f.mu[:3], 0.5, 0.25)[1]
    assert np.allclose(f.P[3:, :3], Gx @ f.P[:3, :3])
    want = Gx @ f.P[:3, :3] @ Gx.T + np.diag([0.0, 0.0, 0.02 ** 2, 0.25 ** 2])
    assert np.allclose(f.P[3:, 3:], want)
    assert f.joint()[0].size == 3  # not yet on the Euclidean map


def test_the_conversion_in_the_filter_is_the_linearised_transform():
    f = _filter()
    rng = np.random.default_rng(4)
    A = rng.normal(size=(7, 7)) * 0.1
    f.mu = np.array([1.0, 2.0, 0.3, 0.5, 0.5, 0.7, 0.3])
    f.P = A @ A.T + 1e-3 * np.eye(7)
    f.idp = [4]
    P0, mu0 = f.P.copy(), f.mu.copy()
    f._to_euclidean(0)
    m, J = idp.to_xy(mu0[3:])
    T = np.zeros((5, 7))
    T[:3, :3] = np.eye(3)
    T[3:, 3:] = J
    assert f.ids == [4] and f.idp == [] and np.allclose(f.mu, np.r_[mu0[:3], m])
    assert np.allclose(f.P, T @ P0 @ T.T)


def test_a_bad_bearing_init_is_a_one_line_error():
    with pytest.raises(FilterError, match="bearing_init = 'inverse': expected 'delayed' or 'inverse_depth'"):
        build_filter("ekf_slam", ring_scenario(3), 0, params={"bearing_init": "inverse"})


def test_the_bearing_only_scenario_ships():
    assert "slam_bearing_only" in shipped_scenarios()
    sc = load_scenario("slam_bearing_only")
    assert not sc.map_known and sc.sensors[0].kind == "bearing"
    assert sc.filter_params["ekf_slam"]["bearing_init"] == "inverse_depth"


def _monte_carlo(init: str, runs: int):
    sc = load_scenario("slam_bearing_only")
    truth = true_beacons(sc)
    ticks = {100: [], 200: [], 400: []}

    def record(flt, st):
        if st.tick in ticks:
            mu, P, ids = flt.joint()
            ticks[st.tick].append((joint_nees(mu, P, ids, st.true_pose, truth), mu.size))

    errs, mapped = [], []
    for s in range(runs):
        f = run(sc, "ekf_slam", 500 + s, params={"bearing_init": init}, on_step=record)[0]
        lm = f.landmarks()
        errs.append(math.sqrt(np.mean([np.sum((m - truth[int(b)]) ** 2) for b, m in zip(lm.ids, lm.means,
                                                                                           strict=True)])))
        mapped.append(len(lm.ids))
    return ticks, np.array(errs), mapped


def test_inverse_depth_is_consistent_and_maps_as_well_as_delayed_initialisation():
    """10 seeded runs of slam_bearing_only (40 s, 5 beacons to map, 2 anchors): with inverse
    depth the joint ANEES (pose and the landmarks converted to Euclidean) at 10, 20 and 40 s
    is inside the 99 % chi-square band, every beacon is on the map at the end, and the final
    map error (RMS over the landmarks) is within 1.5 times the delayed initialisation's. (Measured:
    ANEES 0.83 / 0.91 / 1.25, map RMS 0.0184 +- 0.0018 m against delayed 0.0189 +- 0.0025 m.)"""
    ticks, idp_err, mapped = _monte_carlo("inverse_depth", 10)
    for tick, vals in ticks.items():
        total = sum(d for _, d in vals)
        anees = sum(e for e, _ in vals) / total
        lo, hi = joint_anees_band(1, total, 0.99)
        assert lo <= anees <= hi, f"t = {tick / 10:g} s: joint ANEES {anees:.3f} outside [{lo:.3f}, {hi:.3f}]"
    assert mapped == [5] * 10
    _, delayed_err, _ = _monte_carlo("delayed", 10)
    assert idp_err.mean() < 1.5 * delayed_err.mean(), (idp_err.mean(), delayed_err.mean())
