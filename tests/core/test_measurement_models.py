import numpy as np
import pytest

from beacon_sim.core import measurement_models as mm
from beacon_sim.core.angles import diff

BEACONS = np.array([[3.0, 1.0], [-2.0, 4.0], [-1.0, -3.0], [-5.0, 0.001]])


def numeric_jacobian(h, pose, eps=1e-6, angle_rows=()):
    cols = []
    for i in range(3):
        d = np.zeros(3)
        d[i] = eps
        a, b = np.atleast_1d(h(pose + d)), np.atleast_1d(h(pose - d))
        delta = a - b
        for r in angle_rows:
            delta[r] = diff(a[r], b[r])
        cols.append(delta / (2 * eps))
    return np.stack(cols, axis=1)


@pytest.mark.parametrize("pose", [np.array([0.0, 0.0, 0.0]), np.array([1.0, 2.0, 3.1]),
                                  np.array([-0.5, 0.3, -3.1])])
def test_bearing_jacobian_matches_finite_differences(pose):
    H = mm.bearing_jacobian(pose, BEACONS)
    num = numeric_jacobian(lambda p: mm.bearing(p, BEACONS), pose,
                           angle_rows=range(len(BEACONS)))
    assert np.allclose(H, num, atol=1e-6)


@pytest.mark.parametrize("pose", [np.array([0.0, 0.0, 0.0]), np.array([1.0, 2.0, -3.1])])
def test_range_bearing_jacobian_matches_finite_differences(pose):
    H = mm.range_bearing_jacobian(pose, BEACONS).reshape(-1, 3)
    num = numeric_jacobian(lambda p: mm.range_bearing(p, BEACONS).ravel(), pose,
                           angle_rows=range(1, 2 * len(BEACONS), 2))
    assert np.allclose(H, num, atol=1e-6)


def test_position_and_pose_fix_jacobians():
    pose = np.array([1.0, 2.0, 0.5])
    assert np.allclose(numeric_jacobian(mm.position_fix, pose), mm.POSITION_H)
    assert np.allclose(numeric_jacobian(mm.pose_fix, pose), np.eye(3))


def test_bearing_values_and_wrap():
    # Robot at origin facing +y: a beacon on +x is at -pi/2, one on -x at +pi/2,
    # one behind at -y is at -pi (wrapped into [-pi, pi)).
    pose = np.array([0.0, 0.0, np.pi / 2])
    b = mm.bearing(pose, np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, -1.0]]))
    assert np.allclose(b, [-np.pi / 2, np.pi / 2, -np.pi])


def test_many_forms_agree_with_single_forms():
    poses = np.array([[0.0, 0.0, 0.1], [1.0, -1.0, 2.0], [2.0, 2.0, -3.0]])
    many_b = mm.bearing_many(poses, BEACONS)
    many_r = mm.range_many(poses, BEACONS)
    for i, p in enumerate(poses):
        rb = mm.range_bearing(p, BEACONS)
        assert np.allclose(many_r[i], rb[:, 0])
        assert np.allclose(diff(many_b[i], rb[:, 1]), 0.0)
