"""The fast paths against the general code they stand in for: the same values and the
same verdicts (the slip gain of one command on floats, the runner's slow-step record inline,
the systematic resampler's counts in place)."""

import itertools
import math

import numpy as np
import pytest

from beacon_sim.core.motion import FULL_SLIP_OMEGA, FULL_SLIP_V, MotionNoise
from beacon_sim.core.types import Control, Step
from beacon_sim.filters import resampling
from beacon_sim.hosting.runner import SLOW_WINDOW, FilterRunner, FilterTrack, note_step_time

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
    monkeypatch.setattr("beacon_sim.hosting.runner.time.perf_counter_ns", lambda: next(clock))
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
        # the reference: the same boundaries, np.diff of them as before the fast path
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


def test_the_pfs_unlabeled_test_equals_associations():
    from beacon_sim.core.clutter import UNKNOWN_ID
    from beacon_sim.core.types import Measurement
    from beacon_sim.filters import association
    from beacon_sim.filters.particle.pf import _unlabeled

    cases = []
    for kind, dim in (("bearing", 1), ("range_bearing", 2), ("pose", 3), ("position", 2)):
        for ids in ([1, 2, 3], [UNKNOWN_ID] * 3, [UNKNOWN_ID, 4], [UNKNOWN_ID], [], [7]):
            for dtype in (np.int64, np.int32, np.uint16):
                if dtype is np.uint16 and UNKNOWN_ID in ids:
                    continue
                z = np.zeros((len(ids), dim))
                cases.append(Measurement("s", kind, z, np.asarray(ids, dtype=dtype)))
    cases.append(Measurement("s", "bearing", np.zeros((2, 1)), np.full((2, 1), UNKNOWN_ID)))  # 2-D IDs
    cases.append(Measurement("s", "bearing", np.zeros((2, 1)), np.array([-1.0, -1.0])))  # float IDs
    kinds = set()
    for m in cases:
        assert _unlabeled(m) == association.is_unlabeled(m), m
        kinds.add(_unlabeled(m))
    assert kinds == {True, False}


def _weighted_pose_stats_before(P, w):
    """weighted_pose_stats as it was before its fast path (numpy on the 3x3)."""
    from beacon_sim.core.angles import wrap
    E = np.empty((3, P.shape[1]), dtype=P.dtype)
    wt = np.empty(P.shape[1], dtype=P.dtype)
    wt[:] = w
    mx, my = float(np.dot(wt, P[0])), float(np.dot(wt, P[1]))
    s, c = np.sin(P[2]), np.cos(P[2])
    mth = wrap(math.atan2(float(np.dot(wt, s)), float(np.dot(wt, c))))
    np.subtract(P[0], mx, out=E[0])
    np.subtract(P[1], my, out=E[1])
    e = E[2]
    np.subtract(P[2], mth, out=e)
    if np.any(e >= math.pi):
        np.subtract(e, 2 * math.pi, out=e, where=e >= math.pi)
    if np.any(e < -math.pi):
        np.add(e, 2 * math.pi, out=e, where=e < -math.pi)
    cov = (np.multiply(E, wt) @ E.T).astype(np.float64)
    cov = 0.5 * (cov + cov.T)
    from beacon_sim.filters.particle.pose_stats import above as _above

    clip = not _above(cov, 1e-12)  # the test the code has used since 0.2.0
    if clip:
        vals, vecs = np.linalg.eigh(cov)
        cov = (vecs * np.maximum(vals, 1e-12)) @ vecs.T
        cov = 0.5 * (cov + cov.T)
    return np.array([mx, my, mth]), cov, clip


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_weighted_pose_stats_bit_for_bit_as_before(dtype):
    from beacon_sim.filters.particle.pf import weighted_pose_stats
    rng = np.random.default_rng(7)
    clipped = 0
    for k in range(300):
        n = int(rng.integers(1, 60))
        spread = rng.choice([1e-7, 1e-3, 0.5, 3.0])
        th = (rng.normal(rng.uniform(-3.2, 3.2), spread * 2, n) + math.pi) % (2 * math.pi) - math.pi
        P = np.stack([rng.normal(2.0, spread, n), rng.normal(-1.0, spread, n), th])
        if k % 10 == 0:
            P[:, 1:] = P[:, :1]  # collapsed: the eigenvalue clip
        P = P.astype(dtype)
        w = rng.random(n) ** 3
        w /= w.sum()
        got, (*ref, clip) = weighted_pose_stats(P, w), _weighted_pose_stats_before(P, w)
        clipped += clip
        for a, b in zip(got, ref, strict=True):
            assert a.dtype == b.dtype and np.array_equal(a, b), (k, a, b)
    assert 5 <= clipped < 300  # both paths


def test_the_pfs_eigh_is_numpys():
    from beacon_sim.filters.particle.fast_calls import eigh3 as _eigh
    rng = np.random.default_rng(3)
    for _ in range(200):
        A = rng.normal(size=(3, 3)) * rng.choice([1e-9, 1.0, 1e6])
        S = 0.5 * (A + A.T)
        for x, y in zip(_eigh(S), np.linalg.eigh(S), strict=True):
            assert np.array_equal(x, y) and x.dtype == y.dtype
    with pytest.raises(np.linalg.LinAlgError):  # non-finite: numpy's own error
        _eigh(np.full((3, 3), np.nan))
