import math

import numpy as np
import pytest

from beacon_sim.core.geometry import hdop
from beacon_sim.core.sensors import SensorNoise, SensorSpec, sense, visible_beacons
from beacon_sim.core.types import Beacon
from beacon_sim.core.world import World

WORLD = World((-10.0, -10.0, 10.0, 10.0), (
    Beacon(1, 1.0, 0.0), Beacon(2, 0.0, 2.0), Beacon(3, -3.0, 0.0), Beacon(4, 0.0, -5.0)))
ORIGIN = np.array([0.0, 0.0, 0.0])


def binomial_ok(k, n, p, z=4.5):
    """k successes out of n are compatible with probability p (normal bound, z sigma)."""
    return abs(k - n * p) <= z * math.sqrt(n * p * (1 - p)) + 1


def test_range_limit():
    spec = SensorSpec("s", "range_bearing", max_range=2.5)
    assert visible_beacons(spec, ORIGIN, WORLD).tolist() == [True, True, False, False]


def test_field_of_view_is_centred_on_heading():
    spec = SensorSpec("s", "bearing", fov=math.radians(120))
    # Facing +x: beacon 1 (0 deg) in view, beacon 2 (90 deg) out, 3 behind out, 4 (-90) out.
    assert visible_beacons(spec, ORIGIN, WORLD).tolist() == [True, False, False, False]
    facing_up = np.array([0.0, 0.0, math.pi / 2])
    assert visible_beacons(spec, facing_up, WORLD).tolist() == [False, True, False, False]


def test_detection_rate_within_binomial_bound():
    spec = SensorSpec("s", "bearing", detection_prob=0.3, max_range=4.0)
    rng = np.random.default_rng(5)
    n_calls, seen = 3000, np.zeros(4)
    for _ in range(n_calls):
        m = sense(spec, ORIGIN, WORLD, rng)
        if m is not None:
            for i in m.beacon_ids:
                seen[i - 1] += 1
    assert binomial_ok(seen[0], n_calls, 0.3) and binomial_ok(seen[1], n_calls, 0.3)
    assert binomial_ok(seen[2], n_calls, 0.3)
    assert seen[3] == 0  # out of range: never seen
    # The test must be able to fail: 0.3 is not compatible with 0.35 at this size.
    assert not binomial_ok(seen[0], n_calls, 0.35)


def test_outlier_rate_within_binomial_bound():
    spec = SensorSpec("s", "bearing", outlier_rate=0.2, noise=SensorNoise(bearing_std=1e-6))
    rng = np.random.default_rng(9)
    n_calls, outliers = 2000, 0
    for _ in range(n_calls):
        m = sense(spec, ORIGIN, WORLD, rng)
        outliers += int(np.abs(m.z[0, 0]) > 1e-3)  # beacon 1 is at bearing 0
    assert binomial_ok(outliers, n_calls, 0.2)


def test_bearing_noise_has_the_configured_spread():
    spec = SensorSpec("s", "range_bearing", noise=SensorNoise(bearing_std=0.1, range_std=0.3))
    rng = np.random.default_rng(1)
    z = np.array([sense(spec, ORIGIN, WORLD, rng).z[0] for _ in range(4000)])
    assert np.mean(z[:, 0]) == pytest.approx(1.0, abs=0.03)
    assert np.std(z[:, 0]) == pytest.approx(0.3, rel=0.06)
    assert np.std(z[:, 1]) == pytest.approx(0.1, rel=0.06)


def test_pose_fix_needs_min_beacons_and_averages_noise():
    spec = SensorSpec("s", "pose", max_range=2.5, min_beacons=3,
                      noise=SensorNoise(position_std=0.2, heading_std=0.1))
    rng = np.random.default_rng(0)
    assert sense(spec, ORIGIN, WORLD, rng) is None  # only two beacons in range
    spec = SensorSpec("s", "pose", max_range=3.5, noise=SensorNoise(position_std=0.2, heading_std=0.1))
    zs = np.array([sense(spec, ORIGIN, WORLD, rng).z[0] for _ in range(3000)])
    # Three beacons in range: per-beacon std / sqrt(3).
    assert np.std(zs[:, 0]) == pytest.approx(0.2 / math.sqrt(3), rel=0.07)
    assert np.std(zs[:, 2]) == pytest.approx(0.1 / math.sqrt(3), rel=0.07)
    assert np.allclose(np.mean(zs, axis=0), 0.0, atol=0.01)
    assert spec.fix_std(3).tolist() == pytest.approx([0.2 / math.sqrt(3)] * 2 + [0.1 / math.sqrt(3)])


def test_hdop_hand_computed_cases():
    # Two beacons at right angles, in the plane: G = [[-1, 0], [0, -1]] -> HDOP = sqrt(2).
    assert hdop([0.0, 0.0], [[1.0, 0.0], [0.0, 1.0]]) == pytest.approx(math.sqrt(2))
    # Four beacons on the axes: G^T G = diag(2, 2) -> HDOP = 1.
    four = [[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]]
    assert hdop([0.0, 0.0], four) == pytest.approx(1.0)
    # Height h = 1 above beacons at distance 1: each row shrinks by 1/sqrt(2) -> HDOP doubles^(1/2).
    assert hdop([0.0, 0.0], four, height=1.0) == pytest.approx(math.sqrt(2))
    # Collinear with the receiver: the cross-track position is not fixed.
    assert math.isinf(hdop([0.0, 0.0], [[1.0, 0.0], [2.0, 0.0]]))
    # Vectorised form agrees with the scalar one.
    pts = np.array([[0.0, 0.0], [0.5, 0.2]])
    assert np.allclose(hdop(pts, four), [hdop(p, four) for p in pts])


def test_position_fix_noise_scales_with_hdop():
    spec = SensorSpec("s", "position", min_beacons=2, noise=SensorNoise(position_std=0.05))
    world = World((-5, -5, 5, 5), (Beacon(1, 1.0, 0.0), Beacon(2, 0.0, 1.0)))
    rng = np.random.default_rng(2)
    ms = [sense(spec, ORIGIN, world, rng) for _ in range(3000)]
    assert ms[0].hdop == pytest.approx(math.sqrt(2))
    zs = np.array([m.z[0] for m in ms])
    assert np.std(zs[:, 0]) == pytest.approx(0.05 * math.sqrt(2), rel=0.07)
    assert list(ms[0].beacon_ids) == [1, 2]


def test_sensor_draws_a_fixed_amount_of_randomness():
    """The stream advances the same whatever is seen, so sensors stay reproducible."""
    spec = SensorSpec("s", "bearing", detection_prob=0.5, max_range=2.5)
    a, b = np.random.default_rng(3), np.random.default_rng(3)
    sense(spec, ORIGIN, WORLD, a)
    sense(spec, np.array([9.0, 9.0, 0.0]), WORLD, b)  # sees nothing
    assert a.random() == b.random()
