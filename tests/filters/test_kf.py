"""The linear KF of seed 003 against hand computations."""

import math

import numpy as np
from gaussian_helpers import bearing, belief, context, pose_fix, position_fix, textbook_update

from beacon_sim.core.angles import diff
from beacon_sim.core.types import Control
from beacon_sim.filters.base import GaussianBelief
from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter
from beacon_sim.filters.gaussian.kf import KalmanFilter


def test_predict_is_mu_plus_B_u_and_sigma_plus_R():
    f = KalmanFilter(context())
    f.reset(belief([1.0, 2.0, math.pi / 3], (0.1, 0.2, 0.05)))
    f.predict(Control(0.5, -0.2), 0.1)
    mean, cov = f.estimate()
    # B(theta) u = [dt v cos(theta), dt v sin(theta), dt omega]
    assert np.allclose(mean, [1.0 + 0.05 * 0.5, 2.0 + 0.05 * math.sqrt(3) / 2, math.pi / 3 - 0.02])
    sv = 0.02 + 0.05 * 0.5
    sw = 0.02 + 0.05 * 0.2
    c, s = 0.5, math.sqrt(3) / 2
    R = np.array([[(0.1 * sv * c) ** 2, 0.01 * sv**2 * c * s, 0.0],
                  [0.01 * sv**2 * c * s, (0.1 * sv * s) ** 2, 0.0],
                  [0.0, 0.0, (0.1 * sw) ** 2]]) + np.diag([0.001**2, 0.002**2, 0.001**2])
    assert np.allclose(cov, np.diag([0.01, 0.04, 0.0025]) + R, atol=1e-15)


def test_pose_fix_update_per_axis_by_hand():
    """Diagonal Sigma and Q: each axis is a scalar KF, k = p / (p + q)."""
    f = KalmanFilter(context())
    f.reset(belief([1.0, 2.0, 0.5], (0.2, 0.1, 0.1)))
    f.update([pose_fix([1.3, 1.8, 0.6], n_beacons=4)])  # std (0.1, 0.1, 0.05) / 2
    mean, cov = f.estimate()
    p = np.array([0.04, 0.01, 0.01])
    q = np.array([0.0025, 0.0025, 0.000625])
    k = p / (p + q)
    assert np.allclose(mean, [1.0, 2.0, 0.5] + k * [0.3, -0.2, 0.1], atol=1e-12)
    assert np.allclose(cov, np.diag(p * q / (p + q)), atol=1e-15)


def test_heading_innovation_is_wrapped():
    f = KalmanFilter(context())
    f.reset(belief([0.0, 0.0, math.pi - 0.02], (0.1, 0.1, 0.1)))
    f.update([pose_fix([0.0, 0.0, -math.pi + 0.02], n_beacons=1)])
    mean, _ = f.estimate()
    assert -math.pi <= mean[2] < math.pi
    # innovation +0.04, gain 0.01 / (0.01 + 0.0025) = 0.8: theta = pi - 0.02 + 0.032
    assert abs(diff(mean[2], math.pi + 0.012)) < 1e-12


def test_position_fix_uses_C_equal_I2_0_and_matches_the_textbook():
    P = np.array([[0.04, 0.01, 0.005], [0.01, 0.05, -0.004], [0.005, -0.004, 0.02]])
    f = KalmanFilter(context())
    f.reset(GaussianBelief(np.array([1.0, 2.0, 0.5]), P))
    f.update([position_fix([1.1, 1.95], hdop=2.0)])
    C = np.array([[1.0, 0, 0], [0, 1.0, 0]])
    m_ref, P_ref = textbook_update(np.array([1.0, 2.0, 0.5]), P, [1.1, 1.95], np.array([1.0, 2.0]), C,
                                   np.eye(2) * (0.02 * 2.0) ** 2, angle_rows=[])
    assert np.allclose(f.estimate()[0], m_ref, atol=1e-12)
    assert np.allclose(f.estimate()[1], P_ref, atol=1e-12)


def test_bearing_readings_are_ignored():
    f = KalmanFilter(context())
    f.reset(belief([1.0, 2.0, 0.5], (0.2, 0.1, 0.1)))
    before = f.estimate()
    f.update([bearing([0.3, 0.2], [1, 2])])
    assert np.array_equal(before[0], f.estimate()[0]) and np.array_equal(before[1], f.estimate()[1])


def test_ekf_equals_the_linear_kf_on_a_linear_problem():
    """v = 0 makes the motion linear (F = A = I) and fixes are linear (H = C): the EKF, the
    KF and the textbook equations must give the same numbers at every step."""
    rng = np.random.default_rng(7)
    kf, ekf, ekf_nj = KalmanFilter(context()), ExtendedKalmanFilter(context()), \
        ExtendedKalmanFilter(context({"joseph": False}))
    m = np.array([1.0, 2.0, 3.0])
    P = np.diag([0.04, 0.09, 0.01])
    for f in (kf, ekf, ekf_nj):
        f.reset(GaussianBelief(m.copy(), P.copy()))
    for k in range(40):
        c = Control(0.0, float(rng.normal(0, 0.5)))
        Q = context().motion_noise.process_cov(m, c.v, c.omega, 0.1)
        m = m + np.array([0.0, 0.0, 0.1 * c.omega])
        m[2] = diff(m[2], 0.0)
        P = P + Q
        if k % 2 == 0:
            z = rng.normal([1.0, 2.0, 3.0], 0.1)
            z[2] = diff(z[2], 0.0)
            meas = [pose_fix(z, n_beacons=2)]
            R = np.diag(np.square([0.1, 0.1, 0.05]) / 2)
            m, P = textbook_update(m, P, z, m.copy(), np.eye(3), R, angle_rows=[2])
        else:
            z = rng.normal([1.0, 2.0], 0.05)
            meas = [position_fix(z, hdop=1.5)]
            m, P = textbook_update(m, P, z, m[:2].copy(), np.eye(3)[:2], np.eye(2) * 0.03**2,
                                   angle_rows=[])
        for f in (kf, ekf, ekf_nj):
            f.predict(c, 0.1)
            f.update(meas)
            mean, cov = f.estimate()
            assert np.allclose(mean, m, atol=1e-10), (type(f).__name__, k)
            assert np.allclose(cov, P, atol=1e-12), (type(f).__name__, k)
