"""A reading weighed at N particles (core/particle_likelihood.py), held to the maths: the
built-in kinds' fast forms against the Gaussian log-likelihood of their records' models (the
von Mises bearing term equals the wrapped Gaussian to 4th order in the innovation), the
position fix's per-particle normalisation against the 2-D Gaussian density, and the outlier
mixture against its definition."""

from __future__ import annotations

import math

import numpy as np
import pytest

from beacon_sim.core.geometry import hdop
from beacon_sim.core.particle_likelihood import ParticleFit, with_outliers
from beacon_sim.core.sensor_kinds import model_of
from beacon_sim.core.sensors import SensorNoise, SensorSpec
from beacon_sim.core.types import Beacon, Measurement
from beacon_sim.core.world import World

WORLD = World((0.0, 0.0, 12.0, 9.0),
              tuple(Beacon(i + 1, x, y) for i, (x, y) in enumerate([(1, 1), (11, 1.5), (10, 8), (2, 7.5)])))
TRUE = np.array([5.0, 4.0, 0.7])
NOISE = SensorNoise(range_std=0.1, bearing_std=0.05, position_std=0.2, heading_std=0.05)


class Cloud:
    """The ParticleCloud protocol over plain float64 arrays (what a particle filter lends)."""

    def __init__(self, poses: np.ndarray):
        self.P = np.ascontiguousarray(np.asarray(poses, dtype=float).T)
        self.n = self.P.shape[1]
        self.dtype = np.dtype(np.float64)

    def xy_theta(self):
        return self.P[0], self.P[1], self.P[2]

    def trig(self):
        return np.cos(self.P[2]), np.sin(self.P[2])

    def scratch(self, k):
        return [np.empty((k, self.n)) for _ in range(5)]

    def beacon_columns(self, ids):
        b = WORLD.beacon_positions(ids)
        return b[:, 0:1].copy(), b[:, 1:2].copy()

    def poses64(self):
        return self.P.T.copy()


def _near_truth(n: int, seed: int, spread=(0.05, 0.05, 0.03)) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return TRUE + rng.normal(size=(n, 3)) * np.asarray(spread)


def _fit(kind: str, spec: SensorSpec, m: Measurement, poses: np.ndarray) -> ParticleFit:
    model = model_of(kind)
    assert model is not None
    return model.particle_fit(spec, model.particle_constants(spec), m, Cloud(poses), WORLD)


def _reading(kind: str, spec: SensorSpec) -> Measurement:
    model = model_of(kind)
    ids = WORLD.beacon_ids.copy()   # a fix's beacons (its HDOP and noise); a row each otherwise
    probe = Measurement(spec.name, kind, np.zeros((len(ids) if kind in ("bearing", "range_bearing") else 1,
                                                   len(model.angles))), ids)
    z = model.expected(spec, probe, TRUE[None, :], WORLD)[0].reshape(probe.z.shape)
    return Measurement(spec.name, kind, z, ids, hdop=1.0 if kind == "position" else math.nan)


@pytest.mark.parametrize("kind", ["bearing", "range_bearing", "pose"])
def test_the_fast_forms_are_the_gaussian_to_fourth_order_in_the_angle(kind):
    """Summed over rows, the particle fit differs from the record's Gaussian log-likelihood
    only by the angle terms' ``kappa (cos nu - 1) + nu^2 / (2 sigma^2)``, which lies in
    ``[0, nu^4 / (24 sigma^2)]``."""
    spec = SensorSpec("s", kind, noise=NOISE)
    m = _reading(kind, spec)
    poses = _near_truth(400, 1)
    fit = _fit(kind, spec, m, poses)
    got = fit.fits.sum(axis=0) if fit.fits.ndim == 2 else fit.fits
    model = model_of(kind)
    gauss = model.loglik(spec, m, poses, WORLD)
    nu = model.residual(m, model.expected(spec, m, poses, WORLD))[:, model.angle_rows(m)]
    sigma = spec.fix_std(len(m.beacon_ids))[2] if kind == "pose" else NOISE.bearing_std
    bound = (nu ** 4).sum(axis=1) / (24.0 * sigma ** 2)
    assert np.all(got - gauss >= -1e-9)
    assert np.all(got - gauss <= bound + 1e-9)
    assert float(np.max(bound)) > 1e-6           # the angle innovations were not all zero
    assert fit.dof == len(model.angles) and fit.scalars == m.z.size


def test_the_position_fix_weighs_particles_by_the_gaussian_density_with_their_own_hdop():
    """Between any two particles, ``fits + const`` differs as ``log N(z; p, (s HDOP(p))^2 I)``."""
    spec = SensorSpec("s", "position", noise=NOISE)
    m = _reading("position", spec)
    poses = _near_truth(300, 2, (0.5, 0.5, 0.1))
    fit = _fit("position", spec, m, poses)
    assert fit.const is not None
    sd = NOISE.position_std * hdop(poses[:, :2], WORLD.beacon_xy)
    d2 = np.sum((poses[:, :2] - m.z[0]) ** 2, axis=1)
    density = -d2 / (2 * sd ** 2) - np.log(2 * math.pi * sd ** 2)
    got = fit.fits + fit.const
    assert np.allclose(got - got[0], density - density[0], atol=1e-9)
    assert np.ptp(fit.const) > 1e-3              # HDOP differed between the particles


@pytest.mark.parametrize("kind", ["bearing", "range_bearing", "pose", "position"])
def test_the_outlier_mixture_is_its_definition(kind):
    """``with_outliers`` is ``log((1 - eps) p + eps u)`` relative to the Gaussian's peak, and
    ``log_u`` is the uniform reading's density over that peak: for bearings
    ``(1 / 2 pi) / (1 / sqrt(2 pi sigma^2))``."""
    eps = 0.2
    spec = SensorSpec("s", kind, noise=NOISE, outlier_rate=eps)
    m = _reading(kind, spec)
    poses = _near_truth(50, 3, (1.0, 1.0, 0.5))
    fit = _fit(kind, spec, m, poses)
    assert fit.log_u is not None
    rows = fit.fits.copy() + (0.0 if fit.const is None else fit.const)
    want = np.log((1 - eps) * np.exp(rows) + eps * math.exp(fit.log_u))
    got, left = with_outliers(fit, eps)
    assert np.allclose(got, want, rtol=1e-12, atol=1e-12)
    assert left == (None if fit.const is None else 0.0)
    if kind == "bearing":
        s = NOISE.bearing_std
        peak = 1 / math.sqrt(2 * math.pi * s * s)
        assert fit.log_u == pytest.approx(math.log(1 / (2 * math.pi)) - math.log(peak))
    no = SensorSpec("s", kind, noise=NOISE)
    assert _fit(kind, no, m, poses).log_u is None    # no outliers declared: nothing to mix


def test_a_kind_without_a_fast_form_is_weighed_by_its_log_likelihood():
    """The default ``particle_fit`` (the range kind has none of its own): its model's
    ``loglik`` at the particles, one fit for the whole reading, never mixed."""
    spec = SensorSpec("s", "range", noise=NOISE, params=(("nlos_rate", 0.0), ("nlos_mean", 0.3)))
    m = Measurement("s", "range", np.hypot(*(WORLD.beacon_xy - TRUE[:2]).T)[:, None] + 0.05,
                    WORLD.beacon_ids.copy())
    poses = _near_truth(100, 4)
    fit = _fit("range", spec, m, poses)
    assert np.array_equal(fit.fits, model_of("range").loglik(spec, m, poses, WORLD))
    assert fit.log_u is None and fit.const is None and fit.dof == fit.scalars == m.z.size
