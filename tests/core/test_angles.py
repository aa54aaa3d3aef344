import math

import numpy as np
import pytest

from beacon_sim.core.angles import TWO_PI, circular_mean, diff, wrap, wrap_into


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


def _wrap_by_remainder(a: np.ndarray) -> np.ndarray:
    """The definition: numpy's float remainder of a + pi by a turn, minus pi, with the one
    rounding that lands on pi moved down a turn."""
    w = np.mod(a + np.pi, TWO_PI) - np.pi
    return np.where(w >= np.pi, w - TWO_PI, w)


@pytest.mark.parametrize("scale", [0.5, 3.0, 2 * np.pi, 3 * np.pi, 4 * np.pi, 50.0])
def test_long_arrays_wrap_to_the_remainders_bits(scale):
    """Arrays long enough for the one-turn shift (differences of wrapped angles) and longer
    reaches (numpy's remainder): the bits of the definition, edges and specials included,
    through wrap and wrap_into (with and without scratch)."""
    rng = np.random.default_rng(5)
    edges = np.array([0.0, -0.0, np.pi, -np.pi, TWO_PI, -TWO_PI, 3 * np.pi, -3 * np.pi,
                      np.nextafter(np.pi, 0.0), np.nextafter(-np.pi, 0.0), np.nextafter(-np.pi, -4.0),
                      np.nextafter(3 * np.pi, 0.0), np.nextafter(-3 * np.pi, 0.0), 1e-300, -1e-300,
                      5e-324, -5e-324, -1e-17, 1e-17])
    a = np.concatenate([rng.uniform(-scale, scale, 20001), edges]).reshape(-1, 7)
    want = _wrap_by_remainder(a).view(np.int64)
    assert np.array_equal(wrap(a).view(np.int64), want)
    assert np.array_equal(wrap_into(a.copy()).view(np.int64), want)
    assert np.array_equal(wrap_into(a.copy(), np.empty(a.shape)).view(np.int64), want)


def test_long_arrays_with_nan_or_inf_wrap_as_numpy_does():
    a = np.random.default_rng(6).uniform(-3.0, 3.0, 5000)
    for bad in (np.nan, np.inf, -np.inf, 1e300):
        b = a.copy()
        b[17] = bad
        with np.errstate(invalid="ignore"):  # numpy's remainder of inf is NaN, said
            got, want = wrap(b), _wrap_by_remainder(b)
        assert np.isnan(got[17]) == np.isnan(want[17])
        assert np.array_equal(np.delete(got, 17).view(np.int64), np.delete(want, 17).view(np.int64))
