"""EKF: its hand-written h, H, F and Q against finite differences of the core models, its
stacked update against the textbook matrices, wrapping across +-pi, gating."""

import math

import numpy as np
import pytest
from gaussian_helpers import (
    NOISE,
    bearing,
    belief,
    context,
    pose_fix,
    position_fix,
    range_bearing,
    textbook_update,
)

from beacon_sim.core import measurement_models as mm
from beacon_sim.core import motion
from beacon_sim.core.angles import diff
from beacon_sim.core.types import Control
from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter

POSES = [np.array([5.0, 4.0, 0.3]), np.array([1.0, -2.0, 3.1]), np.array([-3.0, 6.0, -3.1])]
BXY = {1: (2.0, 2.0), 2: (8.0, 2.0), 3: (8.0, 8.0), 4: (2.0, 8.0), 5: (-5.0, 0.001)}


def central_jacobian(f, x, angle_rows=(), eps=1e-6):
    """d f / d x by central differences; differences of angle rows wrapped."""
    cols = []
    for j in range(3):
        dx = np.zeros(3)
        dx[j] = eps
        d = np.asarray(f(x + dx), dtype=float) - np.asarray(f(x - dx), dtype=float)
        for i in angle_rows:
            d[i] = diff(d[i], 0.0)
        cols.append(d / (2 * eps))
    return np.stack(cols, axis=1)


def ekf_at(pose, std=(0.3, 0.3, 0.1), **params):
    f = ExtendedKalmanFilter(context(params))
    f.reset(belief(pose, std))
    return f


def stacked(groups):
    rows = [r for g in groups for r in g]
    H = np.array([r[:3] for r in rows])
    return H, np.array([r[5] for r in rows]), np.array([r[3] for r in rows]), np.array([r[4] for r in rows])


@pytest.mark.parametrize("pose", POSES)
def test_bearing_h_and_H_match_the_model_and_finite_differences(pose):
    ids = [1, 2, 3, 4, 5]
    xy = np.array([BXY[i] for i in ids])
    H, h, _, r = stacked(ekf_at(pose).linearise([bearing(np.zeros(5), ids)]))
    assert np.allclose(h, mm.bearing(pose, xy), atol=1e-12)
    fd = central_jacobian(lambda p: mm.bearing(p, xy), pose, angle_rows=range(5))
    assert np.allclose(H, fd, atol=1e-6)
    assert np.allclose(r, 0.05**2)


@pytest.mark.parametrize("pose", POSES)
def test_range_bearing_h_and_H_match_the_model_and_finite_differences(pose):
    ids = [1, 3, 5]
    xy = np.array([BXY[i] for i in ids])
    H, h, _, r = stacked(ekf_at(pose).linearise([range_bearing(np.zeros((3, 2)), ids)]))
    assert np.allclose(h, mm.range_bearing(pose, xy).reshape(-1), atol=1e-12)
    fd = central_jacobian(lambda p: mm.range_bearing(p, xy).reshape(-1), pose, angle_rows=(1, 3, 5))
    assert np.allclose(H, fd, atol=1e-6)
    assert np.allclose(r, [0.01, 0.0025] * 3)


@pytest.mark.parametrize("pose", POSES)
def test_pose_and_position_fix_h_and_H(pose):
    f = ekf_at(pose)
    H, h, _, r = stacked(f.linearise([pose_fix(pose, n_beacons=4)]))
    assert np.allclose(h, mm.pose_fix(pose))
    assert np.allclose(H, central_jacobian(mm.pose_fix, pose, angle_rows=(2,)), atol=1e-8)
    assert np.allclose(r, np.square([0.05, 0.05, 0.025]))  # std / sqrt(4 beacons)
    H, h, _, r = stacked(f.linearise([position_fix(pose[:2], hdop=1.5)]))
    assert np.allclose(h, mm.position_fix(pose))
    assert np.allclose(H, central_jacobian(mm.position_fix, pose), atol=1e-8)
    assert np.allclose(r, (0.02 * 1.5) ** 2)


@pytest.mark.parametrize("pose", POSES)
@pytest.mark.parametrize("v, omega", [(0.5, 0.2), (-0.3, 1.0), (0.0, -0.5)])
def test_prediction_is_F_P_FT_plus_Q_with_F_by_finite_differences(pose, v, omega):
    dt = 0.1
    rng = np.random.default_rng(3)
    A = rng.normal(size=(3, 3))
    P = A @ A.T * 0.01 + np.eye(3) * 1e-3
    f = ExtendedKalmanFilter(context())
    from beacon_sim.filters.base import GaussianBelief

    f.reset(GaussianBelief(pose, P))
    f.predict(Control(v, omega), dt)
    F = central_jacobian(lambda p: motion.move(p, v, omega, dt), pose, angle_rows=(2,))
    Q = NOISE.process_cov(pose, v, omega, dt)
    mean, cov = f.estimate()
    assert np.allclose(cov, F @ P @ F.T + Q, atol=1e-12)
    assert np.allclose(mean, motion.move(pose, v, omega, dt), atol=1e-12)


@pytest.mark.parametrize("joseph", [True, False])
def test_stacked_update_equals_the_textbook_matrices(joseph):
    """Several sensors and beacons in one tick: the scalar sequence with one linearisation
    point is the stacked update S = H P H^T + R, K = P H^T S^-1 (to rounding)."""
    pose = np.array([4.0, 3.0, 2.9])
    rng = np.random.default_rng(5)
    A = rng.normal(size=(3, 3))
    P = A @ A.T * 0.02 + np.eye(3) * 0.01
    from beacon_sim.filters.base import GaussianBelief

    f = ExtendedKalmanFilter(context({"joseph": joseph}))
    f.reset(GaussianBelief(pose, P))
    ids_b, ids_rb = [1, 2, 5], [3, 4]
    xy_b = np.array([BXY[i] for i in ids_b])
    xy_rb = np.array([BXY[i] for i in ids_rb])
    true = pose + np.array([0.2, -0.1, 0.15])
    zb = diff(mm.bearing(true, xy_b) + 0.03, 0.0)
    zrb = mm.range_bearing(true, xy_rb) + np.array([0.05, -0.02])
    zp = true + np.array([0.05, 0.0, 0.02])
    ms = [bearing(zb, ids_b), range_bearing(zrb, ids_rb), pose_fix(zp, 1)]
    f.update(ms)
    H = np.vstack([mm.bearing_jacobian(pose, xy_b), mm.range_bearing_jacobian(pose, xy_rb).reshape(-1, 3),
                   np.eye(3)])
    h = np.concatenate([mm.bearing(pose, xy_b), mm.range_bearing(pose, xy_rb).reshape(-1), pose])
    z = np.concatenate([zb, zrb.reshape(-1), zp])
    R = np.diag([0.05**2] * 3 + [0.1**2, 0.05**2] * 2 + [0.1**2, 0.1**2, 0.05**2])
    m_ref, P_ref = textbook_update(pose, P, z, h, H, R, angle_rows=[0, 1, 2, 4, 6, 9])
    mean, cov = f.estimate()
    assert np.allclose(mean, m_ref, atol=1e-10)
    assert np.allclose(cov, P_ref, atol=1e-10)


def test_bearing_residual_across_pi_is_wrapped():
    """Beacon 5 is straight behind (bearing pi - 0.0002); a reading of -pi + 0.01 is 0.0102 rad
    more counter-clockwise, not 2 pi less: the heading must move a little clockwise."""
    pose = np.array([0.0, 0.0, 0.0])
    f = ekf_at(pose, std=(0.01, 0.01, 0.1))
    h = mm.bearing(pose, [BXY[5]])[0]
    assert h > math.pi - 1e-3
    f.update([bearing([-math.pi + 0.01], [5])])
    mean, _ = f.estimate()
    assert -0.0103 < mean[2] < 0.0  # bearing = atan2 - theta: a larger bearing, a smaller theta
    assert abs(mean[0]) < 0.01 and abs(mean[1]) < 0.01


def test_heading_wraps_after_update_near_pi():
    f = ekf_at([0.0, 0.0, math.pi - 0.01], std=(0.1, 0.1, 0.1))
    f.update([pose_fix([0.0, 0.0, -math.pi + 0.01], n_beacons=1)])
    mean, _ = f.estimate()
    assert -math.pi <= mean[2] < math.pi
    assert abs(diff(mean[2], math.pi)) < 0.011  # pulled towards pi, not through zero


def test_gate_drops_an_outlier_and_keeps_good_readings():
    pose = np.array([5.0, 5.0, 0.0])
    xy = np.array([BXY[i] for i in (1, 2, 3)])
    good = mm.bearing(pose, xy)
    z = good.copy()
    z[1] = diff(z[1], 2.0)  # 2 rad off: an outlier
    plain = ekf_at(pose, std=(0.05, 0.05, 0.02))
    gated = ekf_at(pose, std=(0.05, 0.05, 0.02), gate_chi2=9.0)
    plain.update([bearing(z, [1, 2, 3])])
    gated.update([bearing(z, [1, 2, 3])])
    assert gated.rejected == 1
    ref = ekf_at(pose, std=(0.05, 0.05, 0.02))
    ref.update([bearing(z[[0, 2]], [1, 3])])
    assert np.allclose(gated.estimate()[0], ref.estimate()[0], atol=1e-12)
    assert np.linalg.norm(plain.estimate()[0] - pose) > 10 * np.linalg.norm(gated.estimate()[0] - pose)


def test_empty_update_and_unusable_kinds_change_nothing():
    f = ekf_at([1.0, 2.0, 0.5])
    before = f.estimate()
    f.update([])
    f.update(())
    after = f.estimate()
    assert np.array_equal(before[0], after[0]) and np.array_equal(before[1], after[1])
