"""Issue 27's fast paths against the general code they stand in for: the same values and the
same verdicts (the slip gain of one command on floats, the runner's slow-step record inline,
the systematic resampler's counts in place)."""

import itertools
import math

import numpy as np
import pytest

from beacon_sim.core.motion import FULL_SLIP_OMEGA, FULL_SLIP_V, MotionNoise
from beacon_sim.core.types import Control, Step
from beacon_sim.filters import resampling
from beacon_sim.filters.runner import SLOW_WINDOW, FilterRunner, FilterTrack, note_step_time

SPECIAL = [0.0, -0.0, 1e-300, 0.01, -0.03, FULL_SLIP_V, -FULL_SLIP_V, FULL_SLIP_OMEGA, 0.07, 0.5, -2.0,
           1e308, -1e308, math.inf, -math.inf, math.nan]


def slip_gain_on_arrays(v, omega):
    """The gain as the array path computes it (0-d arrays take it)."""
    return MotionNoise().slip_gain(np.array(v), np.array(omega))


def same(a, b):
    return (math.isnan(a) and math.isnan(b)) or (a == b and math.copysign(1, a) == math.copysign(1, b))


def test_the_slip_gain_of_one_command_on_floats_equals_the_array_form():
    rng = np.random.default_rng(0)
    pairs = list(itertools.product(SPECIAL, SPECIAL))
    pairs += [(float(v), float(w)) for v, w in rng.normal(0.0, 0.06, (2000, 2))]
    for v, w in pairs:
        fast = MotionNoise().slip_gain(v, w)
        assert type(fast) is float
        assert same(fast, slip_gain_on_arrays(v, w)), (v, w)


def test_the_slip_gain_legacy_and_arrays_are_untouched():
    assert MotionNoise(slip="legacy").slip_gain(0.0, 0.0) == 1.0
    g = MotionNoise().slip_gain(np.array([0.0, 0.01, 1.0]), np.array([0.0, 0.0, 0.0]))
    assert np.array_equal(g, [0.0, 0.01 / FULL_SLIP_V, 1.0])


class Still:
    """A filter that does nothing (its steps' times come from the test's clock)."""

    def predict(self, u, dt):
        pass

    def update(self, z):
        pass

    def estimate(self):
        return np.zeros(3), np.eye(3)


@pytest.mark.parametrize("seed", range(4))
def test_the_runners_slow_step_record_equals_note_step_time(monkeypatch, seed):
    rng = np.random.default_rng(seed)
    # step times [ns]: mostly fast, runs of slow ones, a single slow outlier, around 50 ms
    times = [int(t) for t in rng.choice([1e5, 3e7, 4.9e7, 5e7, 5.1e7, 9e7, 4e8], size=60,
                                        p=[0.4, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1])]
    clock = iter(itertools.chain.from_iterable((0, t) for t in times))
    monkeypatch.setattr("beacon_sim.filters.runner.time.perf_counter_ns", lambda: next(clock))
    runner = FilterRunner({"f": Still()})
    ref = FilterTrack("ref", None)
    tr = runner.tracks["f"]
    step = Step(1, 0.1, 0.1, np.zeros(3), Control(0.0, 0.0))
    for t in times:
        runner.feed(step)
        note_step_time(ref, t)
        assert list(tr.recent_step_ns) == list(ref.recent_step_ns)
        assert tr.recent_sum_ns == ref.recent_sum_ns == sum(ref.recent_step_ns)
        assert tr.slow_warning == ref.slow_warning
    assert len(tr.recent_step_ns) == SLOW_WINDOW


@pytest.mark.parametrize("n_out", [1, 7, 1000])
def test_systematic_resampling_counts_equal_the_diff_of_the_boundaries(n_out):
    rng = np.random.default_rng(n_out)
    for _ in range(50):
        w = rng.random(int(rng.integers(1, 300))) ** 4
        w /= w.sum()
        seed = int(rng.integers(1 << 30))
        idx = resampling.systematic(w, n_out, np.random.default_rng(seed))
        # the reference: the same boundaries, np.diff of them as before issue 27
        c = np.cumsum(w, dtype=np.float64)
        c *= n_out / c[-1]
        c[-1] = n_out
        u = np.random.default_rng(seed).random()
        below = np.clip(np.ceil(c - u).astype(np.int64), 0, n_out)
        ref = np.repeat(np.arange(w.shape[0]), np.diff(below, prepend=0))
        assert np.array_equal(idx, ref)


NOISES = [MotionNoise(), MotionNoise(v_std=0.02, v_frac=0.05, omega_std=0.03, omega_frac=0.1),
          MotionNoise(v_std=1, v_frac=0, omega_std=0.5, omega_frac=2, slip="legacy")]


@pytest.mark.parametrize("noise", NOISES)
def test_control_std_of_one_command_on_floats_equals_the_array_form(noise):
    for v, w in itertools.product(SPECIAL, SPECIAL):
        fast = noise.control_std(v, w)
        with np.errstate(all="ignore"):  # 1e308 * 2 overflows to inf in both forms
            ref = noise.control_std(np.array(v), np.array(w))
        for a, b in zip(fast, ref, strict=True):
            assert type(a) is np.float64
            assert same(float(a), float(b)), (v, w)
