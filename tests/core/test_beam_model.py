"""The beam model (density, sampling) and the likelihood field (distance transform, scores)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from beacon_sim.core.beam_model import (
    LikelihoodField,
    RangeModelParams,
    beam_density,
    distance_transform,
    hit_mass,
    log_beam_likelihood,
    sample_beam,
)
from beacon_sim.core.metrics import chi2_quantile
from beacon_sim.core.occupancy import FREE, OCCUPIED, OccupancyGrid
from beacon_sim.core.raycast import beam_angles, scan
from beacon_sim.errors import UsageError

PARAMS = RangeModelParams(z_hit=0.7, z_short=0.1, z_max=0.05, z_rand=0.15, sigma_hit=0.3,
                          lambda_short=0.8, laser_max_range=8.0)


def simpson(a: float, b: float, f, n: int = 200_001) -> float:
    """Simpson's rule of ``f`` over [a, b], evaluated just inside both ends."""
    if b <= a:
        return 0.0
    z = np.linspace(a, b, n)
    z[0], z[-1] = np.nextafter(a, b), np.nextafter(b, a)
    p = f(z)
    h = (b - a) / (n - 1)
    return float(h / 3 * (p[0] + p[-1] + 4 * p[1:-1:2].sum() + 2 * p[2:-1:2].sum()))


def continuous_integral(z_star: float, params: RangeModelParams) -> float:
    """The density's continuous part over [0, z_max), in two pieces split at z* (where the
    short part stops); the point masses at z_max (and at 0 when z* = 0) are left out."""
    f = lambda z: beam_density(z, z_star, params)  # noqa: E731
    return simpson(0.0, z_star, f) + simpson(z_star, params.laser_max_range, f)


@pytest.mark.parametrize("z_star", [0.0, 0.05, 1.0, 4.0, 7.9, 8.0])
@pytest.mark.parametrize("params", [PARAMS, RangeModelParams(laser_max_range=8.0)], ids=["custom", "amcl"])
def test_the_beam_model_integrates_to_one(z_star, params):
    _w_hit, w_short, w_max, _w_rand = params.weights
    atoms = w_max + (w_short if z_star == 0.0 else 0.0)
    # The short part is steep near 0 for a small z*; Simpson on 400k points is still 1e-7 good.
    assert continuous_integral(z_star, params) + atoms == pytest.approx(1.0, abs=2e-6)


def test_the_density_at_a_point_by_hand():
    z_star, z = 3.0, 3.2
    w = np.array([0.7, 0.1, 0.05, 0.15])
    s, lam, z_max = 0.3, 0.8, 8.0
    phi = lambda x: 0.5 * (1 + math.erf(x / math.sqrt(2)))  # noqa: E731
    eta = phi((z_max - z_star) / s) - phi(-z_star / s)
    hit = math.exp(-0.5 * ((z - z_star) / s) ** 2) / (s * math.sqrt(2 * math.pi)) / eta
    rand = 1 / z_max
    assert beam_density(z, z_star, PARAMS) == pytest.approx(w[0] * hit + w[3] * rand, rel=1e-13)
    # Shorter than z*: the short part joins in.
    z = 1.0
    short = lam * math.exp(-lam * z) / (1 - math.exp(-lam * z_star))
    hit = math.exp(-0.5 * ((z - z_star) / s) ** 2) / (s * math.sqrt(2 * math.pi)) / eta
    want = w[0] * hit + w[1] * short + w[3] * rand
    assert beam_density(z, z_star, PARAMS) == pytest.approx(want, rel=1e-13)
    # At z_max: the point mass counts 1, plus the hit part's tail; no random part.
    hit = math.exp(-0.5 * ((z_max - z_star) / s) ** 2) / (s * math.sqrt(2 * math.pi)) / eta
    assert beam_density(z_max, z_star, PARAMS) == pytest.approx(w[0] * hit + w[2], rel=1e-13)
    assert beam_density(z_max + 5.0, z_star, PARAMS) == beam_density(z_max, z_star, PARAMS)
    assert beam_density(-0.1, z_star, PARAMS) == 0.0


def test_hit_mass_is_the_truncated_normal_mass():
    z_star = np.array([0.0, 0.1, 4.0, 7.95, 8.0])
    phi = lambda x: 0.5 * (1 + math.erf(x / math.sqrt(2)))  # noqa: E731
    want = [phi((8.0 - zs) / 0.3) - phi(-zs / 0.3) for zs in z_star]
    np.testing.assert_allclose(hit_mass(z_star, PARAMS), want, rtol=1e-15)
    assert hit_mass(np.array([0.0]), PARAMS)[0] == pytest.approx(0.5)


def chi_square_statistic(samples: np.ndarray, z_star: float, params: RangeModelParams, bins: int):
    """Pearson's statistic over ``bins`` equal bins of [0, z_max) plus the z_max atom, with the
    expected counts from the density; returns (statistic, degrees of freedom)."""
    z_max = params.laser_max_range
    edges = np.linspace(0.0, z_max, bins + 1)
    probs = []
    for a, b in itertools.pairwise(edges):
        z = np.linspace(a, b, 2001)
        z[0], z[-1] = np.nextafter(a, b), np.nextafter(b, a)
        p = beam_density(z, z_star, params)
        probs.append(np.sum((p[1:] + p[:-1]) / 2 * np.diff(z)))
    probs.append(params.weights[2])
    probs_arr = np.array(probs)
    observed = np.append(np.histogram(samples[samples < z_max], edges)[0], np.sum(samples >= z_max))
    expected = probs_arr / probs_arr.sum() * samples.size
    return float(np.sum((observed - expected) ** 2 / expected)), bins


def chi2_critical(df: int) -> float:
    """The 99.9 % chi-square quantile: a seeded test that fails by chance once in 1000 seeds."""
    return chi2_quantile(0.999, df)


@pytest.mark.parametrize("z_star", [0.4, 3.0, 7.9])
def test_samples_follow_the_density(z_star):
    rng = np.random.default_rng(1234)
    samples = sample_beam(np.full(40_000, z_star), PARAMS, rng)
    assert samples.min() >= 0.0 and samples.max() <= PARAMS.laser_max_range
    stat, df = chi_square_statistic(samples, z_star, PARAMS, bins=40)
    assert stat < chi2_critical(df)


def test_the_chi_square_check_rejects_a_wrong_model():
    rng = np.random.default_rng(99)
    wrong = RangeModelParams(z_hit=0.7, z_short=0.1, z_max=0.05, z_rand=0.15, sigma_hit=0.45,
                             lambda_short=0.8, laser_max_range=8.0)
    samples = sample_beam(np.full(40_000, 3.0), wrong, rng)
    stat, df = chi_square_statistic(samples, 3.0, PARAMS, bins=40)
    assert stat > chi2_critical(df)


def test_sampling_is_deterministic_and_keeps_the_shape():
    z_star = np.linspace(0.0, 8.0, 12).reshape(3, 4)
    a = sample_beam(z_star, PARAMS, np.random.default_rng(5))
    b = sample_beam(z_star, PARAMS, np.random.default_rng(5))
    assert a.shape == (3, 4)
    np.testing.assert_array_equal(a, b)


def test_log_beam_likelihood_sums_over_beams():
    z = np.array([1.0, 3.0, 8.0])
    z_star = np.array([[1.1, 2.9, 8.0], [5.0, 5.0, 5.0]])
    want = np.log(beam_density(z, z_star, PARAMS)).sum(axis=1)
    np.testing.assert_allclose(log_beam_likelihood(z, z_star, PARAMS), want)
    assert want[0] > want[1]


def test_bad_parameters_are_named():
    with pytest.raises(UsageError, match="sigma_hit"):
        RangeModelParams(sigma_hit=0.0)
    with pytest.raises(UsageError, match="z_rand"):
        RangeModelParams(z_rand=-1.0)
    with pytest.raises(UsageError, match="must be > 0"):
        RangeModelParams(z_hit=0, z_short=0, z_max=0, z_rand=0)


# --------------------------------------------------------------------------- likelihood field


def brute_force_distance(occ: np.ndarray) -> np.ndarray:
    rr, cc = np.nonzero(occ)
    if rr.size == 0:
        return np.full(occ.shape, np.inf)
    r, c = np.indices(occ.shape)
    d2 = (r[..., None] - rr) ** 2 + (c[..., None] - cc) ** 2
    return np.sqrt(d2.min(axis=-1))


@pytest.mark.parametrize("seed", range(6))
def test_distance_transform_against_brute_force(seed):
    rng = np.random.default_rng(seed)
    shape = tuple(rng.integers(1, 40, size=2))
    occ = rng.random(shape) < rng.choice([0.005, 0.05, 0.3])
    np.testing.assert_array_equal(distance_transform(occ), brute_force_distance(occ))


@pytest.mark.parametrize("cap", [0.0, 1.0, 2.5, 7.0])
def test_a_capped_distance_transform_is_exact_below_the_cap(cap):
    rng = np.random.default_rng(42)
    occ = rng.random((35, 41)) < 0.01
    np.testing.assert_array_equal(distance_transform(occ, cap), np.minimum(brute_force_distance(occ), cap))


def test_distance_transform_edge_cases():
    assert np.all(np.isinf(distance_transform(np.zeros((3, 4), dtype=bool))))
    assert np.all(distance_transform(np.ones((3, 4), dtype=bool)) == 0.0)
    one = np.zeros((30, 50), dtype=bool)
    one[29, 0] = True   # the far corner: the longest distances of all
    np.testing.assert_array_equal(distance_transform(one), brute_force_distance(one))


def room() -> OccupancyGrid:
    """An 8 m x 6 m room at 0.1 m with a pillar, origin moved and rotated a little."""
    cells = np.zeros((60, 80), dtype=np.int8)
    cells[0, :] = cells[-1, :] = cells[:, 0] = cells[:, -1] = OCCUPIED
    cells[20:30, 45:50] = OCCUPIED
    return OccupancyGrid(cells, 0.1, (1.0, -2.0, 0.2))


def reference_log_likelihood(field: LikelihoodField, poses, ranges, rel) -> np.ndarray:
    """Table 6.3 written out per pose and per beam."""
    p = field.params
    out = []
    for x, y, th in poses:
        total = 0.0
        for z, a in zip(ranges, rel, strict=True):
            if z >= p.laser_max_range:
                continue
            end = np.array([x + z * math.cos(th + a), y + z * math.sin(th + a)])
            row, col = field.grid.world_to_cell(end)
            if field.grid.in_grid(np.array([row, col])):
                d = field.distance[row, col]
            else:
                d = p.laser_likelihood_max_dist
            total += math.log(field.beam_probability(d))
        out.append(total)
    return np.array(out)


def test_the_likelihood_field_matches_table_6_3():
    g = room()
    field = LikelihoodField(g, RangeModelParams(laser_max_range=6.0, laser_likelihood_max_dist=1.0))
    truth = [*g.grid_to_world([20.0, 40.0]).tolist(), 0.7]
    rel, ranges = scan(g, truth, 24, 2 * math.pi, 6.0)
    rng = np.random.default_rng(3)
    # Noise keeps end points off the cell boundaries the exact ranges end on (there, which side
    # a point falls depends on the rounding of the frame change: both are right).
    ranges = np.minimum(ranges + rng.normal(0.0, 0.02, ranges.size), 6.0)
    poses = np.vstack([truth, np.column_stack([rng.uniform(-2, 10, 40), rng.uniform(-4, 6, 40),
                                               rng.uniform(-math.pi, math.pi, 40)])])
    got = field.log_likelihood(poses, ranges, rel, dtype=np.float64)
    np.testing.assert_allclose(got, reference_log_likelihood(field, poses, ranges, rel), rtol=1e-12)
    assert got[0] == got.max()   # the true pose scores best
    # float32 end points: the same cells except within float32 rounding of a cell boundary.
    got32 = field.log_likelihood(poses, ranges, rel, dtype=np.float32)
    close = np.isclose(got32, got, rtol=1e-6)
    assert close.mean() >= 0.9
    per_beam = np.log(field.beam_probability(0.0)) - np.log(field.beam_probability(1.0))
    assert np.all(np.abs(got32 - got) <= 2 * per_beam)


def test_max_range_readings_are_skipped_and_far_poses_score_off_map():
    g = room()
    params = RangeModelParams(laser_max_range=6.0, laser_likelihood_max_dist=1.0)
    field = LikelihoodField(g, params)
    rel = beam_angles(5, 2.0)
    ranges = np.array([1.0, 6.0, 2.0, 7.0, 1.5])
    pose = np.array([[4.0, 1.0, 0.3]])
    full = field.log_likelihood(pose, ranges, rel)
    used = field.log_likelihood(pose, ranges[[0, 2, 4]], rel[[0, 2, 4]])
    assert full[0] == used[0]
    far = field.log_likelihood(np.array([[500.0, -300.0, 0.0]]), ranges, rel)
    assert far[0] == pytest.approx(3 * math.log(field.beam_probability(1.0)))


def test_the_distance_is_capped_and_in_metres():
    cells = np.full((50, 50), FREE, dtype=np.int8)
    cells[25, 25] = OCCUPIED
    field = LikelihoodField(OccupancyGrid(cells, 0.2), RangeModelParams(laser_likelihood_max_dist=1.0))
    assert field.distance[25, 28] == pytest.approx(0.6)
    assert field.distance[25, 45] == 1.0
