"""EKF-SLAM against the maths: the landmark model's Jacobians (pose and landmark) and the
initialisation's against finite differences, the prediction against the full F P F^T, the
joint ANEES over seeded Monte Carlo runs in its chi-square band, and unknown correspondence
building the same map."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from slam_helpers import ring_scenario, run, true_beacons

from beacon_sim.core import motion
from beacon_sim.core.angles import wrap
from beacon_sim.core.types import Control, Measurement
from beacon_sim.evaluation.slam_metrics import gospa, joint_anees_band, joint_nees
from beacon_sim.filters.base import GaussianBelief, LandmarkMap, MappingFilter
from beacon_sim.filters.slam.base import observe, place
from beacon_sim.filters.slam.ekf_slam import EKFSLAM
from beacon_sim.hosting.loading import build_filter

POSES = [np.array([1.0, 2.0, 0.3]), np.array([-1.0, 0.5, 3.1]), np.array([2.0, -3.0, -3.1])]
LMS = [np.array([4.0, 3.0]), np.array([-2.5, -1.0]), np.array([2.2, -2.9])]


def central(f, x, eps=1e-6):
    cols = []
    for j in range(x.size):
        dx = np.zeros(x.size)
        dx[j] = eps
        d = np.asarray(f(x + dx)) - np.asarray(f(x - dx))
        d[-1] = wrap(d[-1])  # the last row is a bearing (or a coordinate: wrapping a tiny value is a no-op)
        cols.append(d / (2 * eps))
    return np.stack(cols, axis=1)


@pytest.mark.parametrize("kind", ["bearing", "range_bearing"])
@pytest.mark.parametrize("i", range(3))
def test_observation_jacobians_match_finite_differences(kind, i):
    pose, lm = POSES[i], LMS[i]
    zhat, Hx, Hm = observe(kind, pose, lm)
    assert np.allclose(Hx[0], central(lambda p: observe(kind, p, lm)[0][0], pose), atol=1e-7)
    assert np.allclose(Hm[0], central(lambda m: observe(kind, pose, m)[0][0], lm), atol=1e-7)
    assert -np.pi <= zhat[0, -1] < np.pi


@pytest.mark.parametrize("i", range(3))
def test_initialisation_inverts_the_model_and_its_jacobians_match(i):
    pose, z = POSES[i], np.array([2.5, -2.9])
    lm, Gx, Gz = place(pose, z)
    back = observe("range_bearing", pose, lm[0])[0][0]
    assert np.allclose(back, z, atol=1e-12)
    assert np.allclose(Gx[0], central(lambda p: place(p, z)[0][0], pose), atol=1e-7)
    assert np.allclose(Gz[0], central(lambda q: place(pose, q)[0][0], z), atol=1e-7)


def _filter_with_landmarks():
    sc = ring_scenario(4)
    f = build_filter("ekf_slam", sc, 0)
    for bid, (x, y) in true_beacons(sc).items():  # map every beacon from the start pose
        pose = f.estimate()[0]
        z = observe("range_bearing", pose, np.array([x, y]))[0]
        f.update([Measurement("beacons", "range_bearing", z, np.array([bid]))])
    return f


def test_prediction_is_the_full_state_jacobian_sandwich():
    f = _filter_with_landmarks()
    mu, P, _ = f.joint()
    v, w, dt = 0.7, -0.4, 0.1
    n = mu.size
    F = np.eye(n)
    F[:3, :3] = motion.jacobian_state(mu[:3], v, dt)
    Q = np.zeros((n, n))
    Q[:3, :3] = f.ctx.motion_noise.process_cov(mu[:3], v, w, dt)
    f.predict(Control(v, w), dt)
    mu2, P2, _ = f.joint()
    assert np.allclose(P2, F @ P @ F.T + Q, atol=1e-14)
    assert np.allclose(mu2[:3], motion.move(mu[:3], v, w, dt)) and np.array_equal(mu2[3:], mu[3:])


def test_update_is_the_textbook_stacked_kalman_update():
    f = _filter_with_landmarks()
    f.predict(Control(0.5, 0.2), 0.5)
    mu, P, ids = f.joint()
    j = 2
    lm = mu[3 + 2 * j:5 + 2 * j]
    z = observe("range_bearing", mu[:3], lm)[0][0] + np.array([0.03, -0.02])
    zhat, Hx, Hm = observe("range_bearing", mu[:3], lm)
    H = np.zeros((2, mu.size))
    H[:, :3], H[:, 3 + 2 * j:5 + 2 * j] = Hx[0], Hm[0]
    R = np.diag(f.ctx.sensor("beacons").reading_std() ** 2)
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    nu = z - zhat[0]
    f.update([Measurement("beacons", "range_bearing", z[None, :], np.array([ids[j]]))])
    mu2, P2, _ = f.joint()
    assert np.allclose(mu2, mu + K @ nu, atol=1e-12)
    assert np.allclose(P2, P - K @ S @ K.T, atol=1e-12)


def test_the_filter_is_a_mapping_filter_and_reports_its_map():
    f = _filter_with_landmarks()
    assert isinstance(f, MappingFilter)
    lm = f.landmarks()
    assert isinstance(lm, LandmarkMap) and lm.means.shape == (4, 2) and lm.covs.shape == (4, 2, 2)
    assert list(lm.ids) == [1, 2, 3, 4]
    assert np.allclose(lm.covs, lm.covs.transpose(0, 2, 1))
    f.reset(GaussianBelief(np.zeros(3), np.eye(3)))
    assert f.landmarks().means.shape == (0, 2)


def _joint_anees(sc, runs, seed0=100):
    """{tick: (joint ANEES, total dof)} at 5, 10 and 20 s over ``runs`` seeded runs."""
    truth = true_beacons(sc)
    times = {50: [], 100: [], 200: []}

    def record(flt, st):
        if st.tick in times:
            mu, P, ids = flt.joint()
            times[st.tick].append((joint_nees(mu, P, ids, st.true_pose, truth), mu.size))

    for seed in range(runs):
        run(sc, "ekf_slam", seed0 + seed, on_step=record)
    out = {}
    for tick, vals in times.items():
        if not vals:
            continue
        total = sum(d for _, d in vals)
        out[tick] = (sum(e for e, _ in vals) / total, total)
    return out


def test_joint_anees_is_in_its_band_over_seeded_monte_carlo_runs():
    """20 runs of 20 s on the benign ring: the average joint NEES (pose and every landmark)
    at 5, 10 and 20 s, against the chi-square band of the total degrees of freedom (99 %
    each, three checks)."""
    for tick, (anees, total) in _joint_anees(ring_scenario(6, duration=20.0), 20).items():
        lo, hi = joint_anees_band(1, total, 0.99)
        assert lo <= anees <= hi, f"t = {tick / 10:g} s: joint ANEES {anees:.3f} outside [{lo:.3f}, {hi:.3f}]"


def test_joint_anees_catches_a_filter_told_too_little_noise():
    """The same check fails for EKF-SLAM told a third of the sensor's noise."""
    sc = ring_scenario(6, duration=10.0)
    told = tuple(replace(s, noise=replace(s.noise, range_std=s.noise.range_std / 3,
                                          bearing_std=s.noise.bearing_std / 3)) for s in sc.model_sensors)
    res = _joint_anees(replace(sc, model_sensors=told), 8)
    anees, total = res[100]
    assert anees > joint_anees_band(1, total, 0.99)[1]


def test_unknown_correspondence_builds_the_same_map_without_duplicates():
    sc = ring_scenario(6, duration=15.0)
    truth = np.array(list(true_beacons(sc).values()))
    known, *_ = run(sc, "ekf_slam", 7)
    blind, *_ = run(sc, "ekf_slam", 7, hide=True)
    assert blind.landmarks().ids is None
    gk = gospa(known.landmarks().means, truth, c=1.0)
    gb = gospa(blind.landmarks().means, truth, c=1.0)
    assert gk.missed == gk.false == 0
    assert gb.missed == gb.false == 0, gb
    assert gb.value < 2 * gk.value + 0.05


def test_unknown_correspondence_with_clutter_keeps_the_map():
    sc = ring_scenario(6, duration=15.0)
    truth = np.array(list(true_beacons(sc).values()))
    blind, *_ = run(sc, "ekf_slam", 8, hide=True, clutter=0.3)
    g = gospa(blind.landmarks().means, truth, c=1.0)
    assert g.missed == 0 and g.false <= 3, g


def test_anchors_are_used_and_not_mapped():
    sc = ring_scenario(6, duration=10.0, anchors=(1, 4))
    assert sorted(b.id for b in sc.filter_world.beacons) == [1, 4]
    f, pose, est, _ = run(sc, "ekf_slam", 3)
    assert sorted(f.landmarks().ids.tolist()) == [2, 3, 5, 6]
    assert np.hypot(*(est[-1, :2] - pose[:2])) < 0.1


def test_same_seed_same_run_bit_for_bit():
    sc = ring_scenario(5, duration=5.0)
    a = run(sc, "ekf_slam", 4, hide=True)[0].joint()
    b = run(sc, "ekf_slam", 4, hide=True)[0].joint()
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])


def test_bearing_only_landmarks_are_triangulated_after_enough_parallax():
    sc = ring_scenario(5, duration=12.0, bearing_only=True, anchors=(1, 2, 3))
    seen = []
    f, pose, est, _ = run(sc, "ekf_slam", 5, on_step=lambda flt, st: seen.append(
        (len(flt.ids), len(flt.copies))))
    assert isinstance(f, EKFSLAM) and seen[0] == (0, 2)  # two pose copies wait for parallax
    lm = f.landmarks()
    assert sorted(lm.ids.tolist()) == [4, 5] and f.copies == []
    truth = true_beacons(sc)
    for bid, m in zip(lm.ids, lm.means, strict=True):
        assert np.hypot(*(m - truth[int(bid)])) < 0.3
    assert np.hypot(*(est[-1, :2] - pose[:2])) < 0.1


def test_triangulation_is_exact_and_its_jacobian_matches_finite_differences():
    from beacon_sim.filters.slam.ekf_slam import triangulate, triangulation_jacobian

    m = np.array([3.0, 4.0])
    p1, p2 = np.array([0.0, 0.0, 0.4]), np.array([2.0, -1.0, 1.9])
    b = [wrap(np.arctan2(m[1] - p[1], m[0] - p[0]) - p[2]) for p in (p1, p2)]
    v = np.concatenate([p1, p2, b])
    assert np.allclose(triangulate(v), m, atol=1e-12)
    G = triangulation_jacobian(v)
    assert np.allclose(G, central(lambda w: np.append(triangulate(w), 0.0), v)[:2], atol=1e-5)
    behind = v.copy()
    behind[6] += np.pi
    assert triangulate(behind) is None


def test_bearing_only_joint_anees_is_in_its_band():
    """Bearing-only EKF-SLAM with two anchors, 20 seeded runs of 20 s on the ring: the joint
    ANEES at 10 and 20 s inside the 99 % band (delayed initialisation keeps it honest)."""
    sc = ring_scenario(6, duration=20.0, bearing_only=True, anchors=(1, 4))
    res = _joint_anees(sc, 20, seed0=500)
    for tick in (100, 200):
        anees, total = res[tick]
        lo, hi = joint_anees_band(1, total, 0.99)
        assert lo <= anees <= hi, f"t = {tick / 10:g} s: joint ANEES {anees:.3f} outside [{lo:.3f}, {hi:.3f}]"


def _two_landmark_state(association):
    """docs/association.md's hand-built case on a SLAM state: landmarks 5 m away at bearings
    +-0.1 rad, mapped to 1 mm, the heading uncertain by 0.2 rad, bearings good to 0.01 rad."""
    sc = ring_scenario(3)
    sc = replace(sc, model_sensors=tuple(replace(s, kind="bearing") for s in sc.model_sensors))
    f = build_filter("ekf_slam", sc, 0, params={"association": association})
    xy = [(5 * np.cos(0.1), 5 * np.sin(0.1)), (5 * np.cos(-0.1), 5 * np.sin(-0.1))]
    f.mu = np.array([0.0, 0.0, 0.0, *xy[0], *xy[1]])
    f.P = np.diag([1e-4, 1e-4, 0.2 ** 2, 1e-6, 1e-6, 1e-6, 1e-6])
    f.ids, f.hits = [-1, -1], [5, 5]
    return f


def test_jcbb_rejects_the_crossed_pairing_nearest_neighbour_takes():
    """The robot truly turned 0.15 rad less than the estimate: it reads landmark 0 at 0.25 rad
    and landmark 1 at 0.05. Nearest neighbour pairs the closest first (0.05 with landmark 0)
    and crosses the pairs; JCBB finds the pairing one heading error explains."""
    z = np.array([[0.25], [0.05]])
    meas = [Measurement("beacons", "bearing", z, np.array([-1, -1]))]
    nn = _two_landmark_state("nn")
    pending = list(nn.readings(meas))
    assert nn.joint_nis(pending, [(0, 1), (1, 0)]) > 100 > 1 > nn.joint_nis(pending, [(0, 0), (1, 1)])
    jc = _two_landmark_state("jcbb")
    jc.update(meas)
    nn.update(meas)
    assert jc.last_method == "jcbb" and nn.last_method == "nn"
    assert jc.last_chosen == {0: 0, 1: 1}
    assert nn.last_chosen == {0: 1, 1: 0}
    # JCBB's pairing: one heading correction of -0.15 rad explains both readings
    assert jc.mu[2] == pytest.approx(-0.15, abs=0.01)


def test_unknown_correspondence_with_nn_and_jcbb_agree_on_a_benign_run():
    sc = ring_scenario(6, duration=10.0)
    truth = np.array(list(true_beacons(sc).values()))
    for assoc in ("nn", "jcbb"):
        f, *_ = run(sc, "ekf_slam", 9, hide=True, clutter=0.2, params={"association": assoc})
        g = gospa(f.landmarks().means, truth, c=1.0)
        assert g.missed == 0 and g.false == 0, (assoc, g)


def test_a_bad_association_name_is_a_one_line_error():
    from beacon_sim.filters.base import FilterError

    with pytest.raises(FilterError, match="association = 'jbcc': expected 'jcbb' or 'nn'"):
        build_filter("ekf_slam", ring_scenario(3), 0, params={"association": "jbcc"})
