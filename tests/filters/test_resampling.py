"""Resampling is unbiased: the expected number of copies of particle i is N w_i."""

import numpy as np
import pytest

from beacon_sim.filters import resampling as R

WEIGHTS = np.array([0.31, 0.002, 0.15, 0.0, 0.07, 0.2, 0.018, 0.1, 0.05, 0.1])


def _mean_counts(fn, w, n_out, trials, seed=3):
    rng = np.random.default_rng(seed)
    counts = np.empty((trials, w.size))
    for t in range(trials):
        counts[t] = np.bincount(fn(w, n_out, rng), minlength=w.size)
    return counts.mean(axis=0), counts.std(axis=0, ddof=1)


def _unbiased(mean, std, expected, trials):
    # z-test per particle; a floor on the standard error covers zero-variance particles.
    se = np.maximum(std / np.sqrt(trials), 1e-3)
    return np.all(np.abs(mean - expected) <= 4.5 * se)


@pytest.mark.parametrize("name", ["systematic", "stratified", "residual", "multinomial"])
@pytest.mark.parametrize("n_out", [10, 7, 23])
def test_expected_copies_equal_n_times_weight(name, n_out):
    trials = 3000
    mean, std = _mean_counts(getattr(R, name), WEIGHTS, n_out, trials)
    expected = n_out * WEIGHTS / WEIGHTS.sum()
    assert _unbiased(mean, std, expected, trials), (name, mean, expected)
    assert mean[3] == 0.0                  # a zero weight is never copied


def test_the_check_catches_a_biased_scheme():
    # Rounding N w down and giving the remainder to the heaviest particle is biased.
    def biased(w, n_out, rng):
        c = np.floor(n_out * w).astype(int)
        c[np.argmax(w)] += n_out - c.sum()
        return np.repeat(np.arange(w.size), c)

    trials = 300
    mean, std = _mean_counts(biased, WEIGHTS, 10, trials)
    assert not _unbiased(mean, std, 10 * WEIGHTS, trials)


def test_systematic_gives_floor_or_ceil_copies():
    rng = np.random.default_rng(0)
    w = rng.random(500) ** 4
    w /= w.sum()
    for _ in range(50):
        c = np.bincount(R.systematic(w, 500, rng), minlength=500)
        assert c.sum() == 500
        assert np.all((c == np.floor(500 * w)) | (c == np.ceil(500 * w)))


@pytest.mark.parametrize("name", R.RESAMPLERS)
def test_output_is_sorted_and_sized(name):
    rng = np.random.default_rng(1)
    idx = R.resample(name, WEIGHTS, 1000, rng)
    assert idx.shape == (1000,)
    assert np.all(np.diff(idx) >= 0)
    assert idx.min() >= 0 and idx.max() < WEIGHTS.size


def test_effective_sample_size():
    assert R.effective_sample_size(np.full(8, 1 / 8)) == pytest.approx(8.0)
    assert R.effective_sample_size(np.array([1.0, 0, 0])) == pytest.approx(1.0)
    assert R.effective_sample_size(np.array([0.5, 0.5, 0, 0])) == pytest.approx(2.0)


def test_unknown_resampler():
    with pytest.raises(ValueError, match="systematic"):
        R.resample("bogus", WEIGHTS, 3, np.random.default_rng(0))
