"""The posterior Cramer-Rao bound: equal to the Kalman covariance where the problem is
linear and Gaussian, the expected information of a detection, and below an EKF's MSE."""

from __future__ import annotations

import math

import numpy as np
import pytest

from beacon_sim.core import measurement_models as mm
from beacon_sim.core.geometry import hdop
from beacon_sim.core.scenario import load_scenario, parse_scenario
from beacon_sim.core.sensors import SensorNoise, SensorSpec
from beacon_sim.core.simulation import scenario_with_slip
from beacon_sim.evaluation.montecarlo import run_monte_carlo
from beacon_sim.evaluation.pcrb import measurement_information, pcrb
from beacon_sim.evaluation.summary import evaluate

BEACONS = [{"id": 1, "x": 2.0, "y": 2.0}, {"id": 2, "x": 8.0, "y": 3.0},
           {"id": 3, "x": 4.0, "y": 8.0}]


def _static(sensor: dict, pose_std=(0.05, 0.04, 0.02)):
    """A robot standing still (v = 0, so F = I) with additive pose noise: linear-Gaussian.
    The legacy slip model: the "scaled" one has no noise at standstill."""
    return scenario_with_slip(parse_scenario({
        "name": "static", "dt": 0.1,
        "world": {"bounds": [0.0, 0.0, 10.0, 10.0], "beacons": BEACONS},
        "robot": {"initial_pose": [5.0, 4.0, 0.3], "motion_noise": {"pose_std": list(pose_std)}},
        "sensors": [sensor],
        "driver": {"kind": "constant", "v": 0.0, "omega": 0.0},
    }, "<test>"), "legacy")


def _kalman_covariances(P0, Q, R_of_step, T):
    """Textbook KF covariance recursion, gain form: P- = P + Q (F = I); K = P- H^T S^-1."""
    P = P0.copy()
    out = []
    for k in range(T):
        P = P + Q
        H, R = R_of_step(k)
        S = H @ P @ H.T + R
        K = P @ H.T @ np.linalg.inv(S)
        P = (np.eye(3) - K @ H) @ P
        out.append(P)
    return np.array(out)


def test_pose_fix_bound_equals_kalman_covariance_and_riccati_fixed_point():
    sc = _static({"name": "fix", "kind": "pose", "position_std": 0.2, "heading_std": 0.1})
    T = 300
    truths = np.tile(np.array(sc.initial_pose), (1, T + 1, 1))
    controls = np.zeros((1, T, 2))
    P0 = np.diag([0.3, 0.2, 0.1]) ** 2
    bound = pcrb(sc, truths, controls, initial_cov=P0)[0]
    # Three beacons in view, detected with probability 1: a fix averaged over 3 beacons.
    R = np.diag([0.2**2 / 3, 0.2**2 / 3, 0.1**2 / 3])
    Q = np.diag([0.05, 0.04, 0.02]) ** 2
    kf = _kalman_covariances(P0, Q, lambda k: (np.eye(3), R), T)
    np.testing.assert_allclose(bound, kf, rtol=1e-9, atol=1e-15)
    # Scalar Riccati fixed point per axis: p = (p + q) r / (p + q + r).
    for i in range(3):
        q, r = Q[i, i], R[i, i]
        p = (-q + math.sqrt(q * q + 4 * q * r)) / 2
        assert bound[-1, i, i] == pytest.approx(p, rel=1e-9)


def test_position_fix_bound_equals_kalman_covariance_along_a_moving_truth():
    sc = _static({"name": "ulps", "kind": "position", "position_std": 0.05,
                  "min_beacons": 2, "beacon_height": 2.0})
    T = 200
    rng = np.random.default_rng(5)
    truths = np.empty((1, T + 1, 3))
    truths[0, 0] = sc.initial_pose
    truths[0, 1:] = sc.initial_pose + np.cumsum(rng.normal(0, 0.05, (T, 3)), axis=0)
    P0 = np.diag([0.1, 0.1, 0.05]) ** 2
    bound = pcrb(sc, truths, np.zeros((1, T, 2)), initial_cov=P0)[0]
    bxy = sc.world.beacon_xy
    Hxy = np.array([[1.0, 0, 0], [0, 1.0, 0]])

    def fix(k):
        s = 0.05 * hdop(truths[0, k + 1, :2], bxy, 2.0)
        return Hxy, np.eye(2) * s * s

    kf = _kalman_covariances(P0, np.diag([0.05, 0.04, 0.02]) ** 2, fix, T)
    np.testing.assert_allclose(bound, kf, rtol=1e-9, atol=1e-15)


def test_detection_probability_scales_information_and_bounds_the_kalman_average():
    """With p_detect = 0.5 the bound uses half the information; the average KF covariance
    over random detection sequences is larger (Jensen), and the p = 1 bound smaller."""
    base = {"name": "fix", "kind": "pose", "position_std": 0.2, "heading_std": 0.1,
            "max_range": 3.7}  # beacons 1 (3.6 m) and 2 (3.16 m) in range, 3 (4.1 m) not
    sc_half = _static({**base, "detection_prob": 0.5})
    sc_one = _static({**base, "detection_prob": 1.0})
    pose = np.array(sc_half.initial_pose)
    in_range = np.hypot(*(sc_half.world.beacon_xy - pose[:2]).T) <= 3.7
    n = int(in_range.sum())
    assert n == 2  # beacons 1 and 2 are within 3.7 m of (5, 4)
    info = measurement_information(sc_half.sensors[0], pose[None], sc_half.world.beacon_xy)[0]
    # E[n_detected] with n ~ Binomial(2, 0.5) is 1; a fix from k beacons has info k R1^-1.
    np.testing.assert_allclose(info, np.diag([1 / 0.04, 1 / 0.04, 1 / 0.01]), rtol=1e-12)

    T = 150
    truths = np.tile(pose, (1, T + 1, 1))
    P0 = np.diag([0.3, 0.2, 0.1]) ** 2
    b_half = pcrb(sc_half, truths, np.zeros((1, T, 2)), initial_cov=P0)[0]
    b_one = pcrb(sc_one, truths, np.zeros((1, T, 2)), initial_cov=P0)[0]
    rng = np.random.default_rng(1)
    Q = np.diag([0.05, 0.04, 0.02]) ** 2
    R1 = np.diag([0.04, 0.04, 0.01])
    avg = np.zeros((T, 3, 3))
    trials = 400
    for _ in range(trials):
        k_det = rng.binomial(2, 0.5, T)

        def step(k, k_det=k_det):
            if k_det[k] == 0:
                return np.zeros((0, 3)), np.zeros((0, 0))
            return np.eye(3), R1 / k_det[k]

        avg += _kalman_covariances(P0, Q, step, T) / trials
    for P_b, P_kf in ((b_one, b_half), (b_half, avg)):
        gap = np.linalg.eigvalsh(P_kf[10:] - P_b[10:])
        assert gap.min() > 0.0


@pytest.mark.parametrize("kind", ["bearing", "range_bearing"])
def test_beacon_information_matches_finite_difference_fisher_information(kind):
    """I = p * J^T R^-1 J with J = dh/dpose by central differences; beacons outside the
    field of view add nothing."""
    spec = SensorSpec("s", kind, fov=math.pi, detection_prob=0.7,
                      noise=SensorNoise(bearing_std=0.05, range_std=0.1))
    bxy = np.array([[4.0, 1.0], [3.0, 4.0], [-2.0, 0.5]])  # the last one is behind the robot
    pose = np.array([1.0, 1.5, 0.2])
    h = (lambda p: mm.bearing(p, bxy[:2])) if kind == "bearing" else \
        (lambda p: mm.range_bearing(p, bxy[:2]).reshape(-1))
    eps = 1e-6
    J = np.stack([(h(pose + eps * e) - h(pose - eps * e)) / (2 * eps) for e in np.eye(3)], axis=1)
    std = spec.reading_std()
    Rinv = np.diag(np.tile(1.0 / std**2, 2))
    expected = 0.7 * J.T @ Rinv @ J
    got = measurement_information(spec, pose[None], bxy)[0]
    np.testing.assert_allclose(got, expected, rtol=1e-6)


def test_bound_lies_below_the_ekf_mse_on_bearing_only_tracking():
    """Seed 000's bearing-only problem before its kidnap: strongly nonlinear; the EKF's
    position and heading MSE over 24 runs stay above the bound."""
    sc = load_scenario("krejsa_bearing_only")
    runs = run_monte_carlo(sc, ["ekf"], 24, seed=0, duration=25.0, jobs=1, progress=False)
    meta, curves = evaluate(sc, runs)
    row = meta["filters"]["ekf"]
    assert row["pos_rmse_m"] > 1.1 * meta["pcrb"]["pos_rmse_m"]
    assert row["heading_rmse_rad"] > meta["pcrb"]["heading_rmse_rad"]
    # And at (almost) every moment: the run-averaged squared error is above the bound
    # (the first second is excluded: both start at zero error).
    late = curves["time"] > 1.0
    assert np.mean(curves["filters"]["ekf"]["rmse_t"][late] >= curves["pcrb_pos_t"][late]) > 0.9
