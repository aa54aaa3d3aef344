import numpy as np
import pytest

from beacon_sim.core import motion


def central_diff(f, x, eps=1e-6):
    x = np.asarray(x, dtype=float)
    cols = []
    for i in range(x.size):
        dx = np.zeros_like(x)
        dx[i] = eps
        a, b = f(x + dx), f(x - dx)
        d = a - b
        cols.append(d / (2 * eps))
    return np.stack(cols, axis=1)


@pytest.mark.parametrize("theta", [0.0, 0.7, 2.5, -2.9, np.pi - 1e-3])
def test_state_jacobian_matches_finite_differences(theta):
    pose = np.array([1.0, -2.0, theta])
    v, w, dt = 0.8, -0.4, 0.1

    def f(p):
        out = motion.move(p, v, w, dt)
        out[2] = p[2] + w * dt  # compare unwrapped: the wrap is not part of the derivative
        return out

    assert np.allclose(motion.jacobian_state(pose, v, dt), central_diff(f, pose), atol=1e-8)


@pytest.mark.parametrize("theta", [0.0, 1.2, -2.0])
def test_control_jacobian_matches_finite_differences(theta):
    pose = np.array([0.5, 0.5, theta])
    dt = 0.2

    def f(u):
        out = motion.move(pose, u[0], u[1], dt)
        out[2] = pose[2] + u[1] * dt
        return out

    assert np.allclose(motion.jacobian_control(pose, dt), central_diff(f, np.array([0.3, 0.1])),
                       atol=1e-8)


def test_move_straight_and_turn_and_wrap():
    p = motion.move(np.array([0.0, 0.0, np.pi / 2]), 1.0, 0.0, 2.0)
    assert np.allclose(p, [0.0, 2.0, np.pi / 2])
    p = motion.move(np.array([0.0, 0.0, 3.0]), 0.0, 1.0, 0.5)
    assert p[2] == pytest.approx(3.5 - 2 * np.pi)


def test_move_many_poses_with_per_pose_controls():
    poses = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, np.pi]])
    out = motion.move(poses, np.array([1.0, 2.0]), np.array([0.0, 0.5]), 0.5)
    assert np.allclose(out[0], [0.5, 0.0, 0.0])
    assert np.allclose(out[1], [0.0, 1.0, -np.pi + 0.25])


def test_process_cov_is_b_m_bt_plus_pose_noise():
    noise = motion.MotionNoise(v_std=0.1, v_frac=0.25, omega_std=0.05, pose_std=(0.01, 0.02, 0.0))
    pose = np.array([0.0, 0.0, 0.3])
    Q = noise.process_cov(pose, 0.4, 0.2, 0.1)
    sv = 0.1 + 0.25 * 0.4
    B = motion.jacobian_control(pose, 0.1)
    expected = B @ np.diag([sv**2, 0.05**2]) @ B.T + np.diag([1e-4, 4e-4, 0.0])
    assert np.allclose(Q, expected)
    assert np.allclose(Q, Q.T) and np.min(np.linalg.eigvalsh(Q)) >= 0
