import math

import numpy as np
import pytest

from beacon_sim.core.angles import circular_mean, diff, wrap


@pytest.mark.parametrize(
    "angle, expected",
    [(0.0, 0.0), (math.pi, -math.pi), (-math.pi, -math.pi), (3 * math.pi, -math.pi),
     (math.pi - 1e-12, math.pi - 1e-12), (2 * math.pi, 0.0), (-3 * math.pi / 2, math.pi / 2),
     (7.0, 7.0 - 2 * math.pi)],
)
def test_wrap_scalar(angle, expected):
    assert wrap(angle) == pytest.approx(expected, abs=1e-12)
    assert -math.pi <= wrap(angle) < math.pi


def test_wrap_array_stays_in_half_open_interval():
    a = np.linspace(-20, 20, 100001)
    w = wrap(a)
    assert np.all(w >= -np.pi) and np.all(w < np.pi)
    assert np.allclose(np.sin(w), np.sin(a)) and np.allclose(np.cos(w), np.cos(a))


def test_diff_across_pi():
    # 179 deg minus -179 deg is -2 deg, not 358 deg.
    a, b = math.radians(179), math.radians(-179)
    assert diff(a, b) == pytest.approx(math.radians(-2))
    assert diff(b, a) == pytest.approx(math.radians(2))


def test_circular_mean_across_pi():
    angles = np.array([math.pi - 0.1, -math.pi + 0.1])
    m = circular_mean(angles)
    assert abs(diff(m, math.pi)) < 1e-12  # arithmetic mean would give 0
    assert circular_mean([0.1, 0.3], weights=[3, 1]) == pytest.approx(
        math.atan2(3 * math.sin(0.1) + math.sin(0.3), 3 * math.cos(0.1) + math.cos(0.3)))
