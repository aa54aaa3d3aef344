"""How a reading is weighed at N particles: the particle side of a sensor kind's measurement
model (core/sensor_kind.py), which any particle filter composes.

A filter lends its particles as a :class:`ParticleCloud` (rows x, y, theta in its own
dtype, their cosines and sines, scratch arrays, the beacons' coordinates as columns) and
asks the model of the reading's kind for its :meth:`MeasurementModel.particle_fit
<beacon_sim.core.sensor_kind.MeasurementModel.particle_fit>`: a :class:`ParticleFit`, the
Gaussian log-likelihood of the reading at every particle with the constants that are the
same at every particle left out (so each term is <= 0, 0 at a perfect fit), per row or for
the whole reading. The filter keeps its book-keeping: it tallies the fits for its lost test
(chi-square with ``dof`` degrees of freedom), mixes in the sensor's declared outlier share
with :func:`with_outliers` and adds the result to its log-weights.

This module holds the fast forms of the built-in kinds, on arrays of the particles' dtype:

- bearing and range-bearing (:func:`von_mises_fit`): the bearing term in the von Mises form
  ``kappa (cos(innovation) - 1)``, ``kappa = 1 / sigma^2``, equal to the wrapped Gaussian to
  4th order in the innovation, with no arctan and no wrap; a range adds its Gaussian term;
- pose fixes (:func:`pose_fit`): Gaussian in x, y and von Mises in the heading;
- position fixes (:func:`position_fit`): Gaussian with ``sigma = position_std * HDOP`` at
  each particle (seed 002 eq. 11), with the per-particle normalisation that follows.

Any other kind gets the model's default: its ``loglik`` on the particles as float64 poses.
Frames and units: poses ``[x, y, theta]`` [m, m, rad], world frame.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, NamedTuple, Protocol

import numpy as np

from beacon_sim.core.geometry import hdop
from beacon_sim.core.sensors import SensorSpec
from beacon_sim.core.types import Measurement
from beacon_sim.core.world import World

TWO_PI = 2.0 * math.pi


class ParticleCloud(Protocol):
    """What a particle filter lends a kind's particle likelihood: its ``n`` particles (in
    ``dtype``) and the filter's own buffers, so that weighing a reading allocates nothing."""

    n: int
    dtype: np.dtype

    def xy_theta(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The particles' x [m], y [m] and theta [rad], each (n,) (views: read only)."""
        ...

    def trig(self) -> tuple[np.ndarray, np.ndarray]:
        """cos(theta) and sin(theta) of the particles, each (n,) (the filter's buffers)."""
        ...

    def scratch(self, k: int) -> Sequence[np.ndarray]:
        """Five (k, n) work arrays of ``dtype`` (overwritten by the next reading)."""
        ...

    def beacon_columns(self, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The x and y [m] of the beacons ``ids`` as columns (k, 1) of ``dtype``."""
        ...

    def poses64(self) -> np.ndarray:
        """The particles as float64 poses (n, 3) (a copy)."""
        ...


class ParticleFit(NamedTuple):
    """A reading weighed at every particle.

    Attributes
    ----------
    fits : ndarray, shape (k, n) or (n,)
        Gaussian log-likelihood of each row of the reading (k, n), or of the whole reading
        (n,), constants that are the same at every particle left out (<= 0). May be one of
        the cloud's scratch arrays.
    dof : int
        Degrees of freedom of one row of ``fits`` (the lost test's chi-square).
    scalars : int
        How many scalar readings ``m`` holds.
    log_u : float or None
        Log density of an outlier (a reading uniform over what the sensor can read)
        relative to the Gaussian's peak, for the outlier mixture (:func:`with_outliers`);
        None: the kind is not mixed with outliers. Only asked for when the sensor declares
        outliers.
    const : ndarray of shape (n,), or None
        A normalisation that differs between particles (a position fix's HDOP), to add to
        the log-weights beside ``fits``; None: none.
    """

    fits: np.ndarray
    dof: int
    scalars: int
    log_u: float | None = None
    const: np.ndarray | None = None


def with_outliers(fit: ParticleFit, eps: float) -> tuple[np.ndarray, np.ndarray | float | None]:
    """``fit`` mixed with the outlier density: ``log((1 - eps) p + eps u)`` per row, relative
    to the Gaussian's peak (``eps`` the sensor's outlier rate, ``fit.log_u`` the outlier's
    density). Returns the mixed fits (rows of a (k, n) fit written in place) and what is left
    of ``fit.const`` to add apart (0.0: it went into the mixture; None: there was none)."""
    assert fit.log_u is not None
    if fit.const is None:
        mixed = np.logaddexp(fit.fits + math.log1p(-eps), math.log(eps) + fit.log_u)
        const = None
    else:
        mixed = np.logaddexp(fit.fits + fit.const + math.log1p(-eps), math.log(eps) + fit.log_u)
        const = 0.0
    if fit.fits.ndim == 2:
        fit.fits[:] = mixed
        return fit.fits, const
    return mixed, const


def beacon_constants(spec: SensorSpec) -> tuple[np.ndarray, float]:
    """A beacon sensor's reading standard deviations ``[sb]`` or ``[sr, sb]`` and the
    bearing's von Mises concentration ``kappa = 1 / sb^2`` [1/rad^2]."""
    std = spec.reading_std()
    return std, 1.0 / std[-1] ** 2


def von_mises_fit(spec: SensorSpec, consts: Any, m: Measurement, cloud: ParticleCloud,
                  world: World, ranged: bool) -> ParticleFit:
    """Bearings (``ranged`` False) or range-bearing readings at every particle, one row per
    beacon: ``kappa (cos(nu) - 1)`` with ``cos(nu) = [cos(theta + z) dx + sin(theta + z) dy]
    / r`` for the bearing (``(dx, dy)`` beacon minus particle, r its length), plus
    ``-0.5 ((r - z_r) / s_r)^2`` for a range. ``consts``: :func:`beacon_constants`."""
    std, kappa = consts
    x, y, _ = cloud.xy_theta()
    z = np.asarray(m.z, dtype=float)
    bx, by = cloud.beacon_columns(m.beacon_ids)
    k = z.shape[0]
    T1, T2, T3, DX, DY = cloud.scratch(k)
    c, s = cloud.trig()
    dtype = cloud.dtype
    cz = np.cos(z[:, -1]).astype(dtype)[:, None]
    sz = np.sin(z[:, -1]).astype(dtype)[:, None]
    np.subtract(bx, x, out=DX)
    np.subtract(by, y, out=DY)
    # cos(innovation) = [cos(theta + z) dx + sin(theta + z) dy] / r,
    # cos(theta + z) = c cz - s sz, sin(theta + z) = s cz + c sz.
    np.multiply(c, cz, out=T1)
    np.multiply(s, sz, out=T2)
    T1 -= T2
    T1 *= DX
    np.multiply(s, cz, out=T2)
    np.multiply(c, sz, out=T3)
    T2 += T3
    T2 *= DY
    T1 += T2
    np.multiply(DX, DX, out=T2)
    np.multiply(DY, DY, out=T3)
    T2 += T3
    np.sqrt(T2, out=T2)                   # range r
    if not ranged:                        # r is not needed after: in place
        np.maximum(T2, 1e-6, out=T2)
        T1 /= T2
    else:
        np.maximum(T2, 1e-6, out=T3)
        T1 /= T3
    T1 -= 1.0
    T1 *= kappa                           # von Mises: kappa (cos(nu) - 1) <= 0
    if ranged:
        T2 -= z[:, 0:1].astype(dtype)
        T2 *= 1.0 / std[0]
        T2 *= T2
        T2 *= -0.5
        T1 += T2                          # Gaussian range term
    log_u = None
    if spec.outlier_rate > 0:
        # uniform over the bearings (and the ranges up to max_range, else the world's diagonal)
        log_u = -math.log(TWO_PI) + 0.5 * math.log(TWO_PI * std[-1] ** 2)
        if ranged:
            rmax = spec.max_range if math.isfinite(spec.max_range) else math.hypot(world.width, world.height)
            log_u += -math.log(rmax) + 0.5 * math.log(TWO_PI * std[0] ** 2)
    return ParticleFit(T1, 2 if ranged else 1, int(z.size), log_u)


def pose_fit(spec: SensorSpec, m: Measurement, cloud: ParticleCloud, world: World) -> ParticleFit:
    """A pose fix ``[x, y, theta]`` at every particle: Gaussian in x and y, von Mises in the
    heading, its standard deviations shrinking with the beacons used (``SensorSpec.fix_std``);
    an outlier is uniform over the world and all headings."""
    x, y, th = cloud.xy_theta()
    z = np.asarray(m.z, dtype=float)
    std = spec.fix_std(len(m.beacon_ids))
    ex = (x - z[0, 0]) / std[0]
    ey = (y - z[0, 1]) / std[1]
    row = -0.5 * (ex.astype(np.float64) ** 2 + ey ** 2)
    row += (np.cos(th - z[0, 2]) - 1.0) / std[2] ** 2
    log_u = None
    if spec.outlier_rate > 0:
        area = world.width * world.height
        log_u = -math.log(area * TWO_PI) + math.log(TWO_PI * std[0] * std[1]) \
            + 0.5 * math.log(TWO_PI * std[2] ** 2)
    return ParticleFit(row, 3, 3, log_u)


def position_fit(spec: SensorSpec, m: Measurement, cloud: ParticleCloud, world: World) -> ParticleFit:
    """A position fix ``[x, y]`` at every particle: Gaussian with ``sigma = position_std *
    HDOP`` of the particle's own geometry (seed 002 eq. 11), so the 2-D normalisation
    ``1 / (2 pi sigma^2)`` differs between particles: it is returned as ``const``, relative
    to the reported fix's sigma. An outlier is uniform over the world."""
    x, y, _ = cloud.xy_theta()
    z = np.asarray(m.z, dtype=float)
    bxy = world.beacon_positions(m.beacon_ids)
    xy = np.stack([x, y], axis=1)
    h = np.minimum(hdop(xy, bxy, spec.beacon_height), 1e3)
    sd = spec.noise.position_std * h            # seed 002: sigma = HDOP(x_l, y_l) sigma_d
    sd0 = spec.noise.position_std * (m.hdop if math.isfinite(m.hdop) else float(np.min(h)))
    d2 = (x - z[0, 0]).astype(np.float64) ** 2 + (y - z[0, 1]) ** 2
    row = -0.5 * d2 / sd**2
    const = -2.0 * np.log(sd / sd0)
    log_u = None
    if spec.outlier_rate > 0:
        area = world.width * world.height
        log_u = -math.log(area) + math.log(TWO_PI * sd0**2)
    return ParticleFit(row, 2, 2, log_u, const)


__all__ = ["ParticleCloud", "ParticleFit", "beacon_constants", "pose_fit", "position_fit",
           "von_mises_fit", "with_outliers"]
