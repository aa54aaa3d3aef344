"""Range-finder sensor models: the beam model and the likelihood field (Probabilistic
Robotics ch. 6.3 and 6.4), with AMCL's parameter names.

The beam model's density of one reading z [m] given the expected range z* [m] (ray cast):

    p(z | z*) = z_hit p_hit + z_short p_short + z_max p_max + z_rand p_rand     (eq. 6.12)

    p_hit   = N(z; z*, sigma_hit^2) / eta,  0 <= z <= z_max,  eta = its mass on [0, z_max]
    p_short = lambda e^(-lambda z) / (1 - e^(-lambda z*)),  0 <= z <= z*
    p_max   = 1 at z = z_max (a point mass: a reading at or beyond the maximum is z_max)
    p_rand  = 1 / z_max,  0 <= z < z_max

The weights are divided by their sum (AMCL's defaults sum to 1.1), so the continuous part
integrated over [0, z_max) plus the point mass at z_max is one. At z* = 0 the short part is a
point mass at z = 0 (its limit).

The likelihood field (Table 6.3) scores a beam by the distance d [m] from its end point to the
nearest occupied cell: ``z_hit N(d; 0, sigma_hit^2) + z_rand / z_max``, d capped at
``laser_likelihood_max_dist`` (AMCL's cap; off the map d is the cap); readings at z_max are
skipped. The distance transform is exact (Euclidean, between cell centres).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from beacon_sim.core import portable_math as pm
from beacon_sim.core.occupancy import OccupancyGrid
from beacon_sim.core.optional import optional
from beacon_sim.errors import UsageError

_SQRT2 = math.sqrt(2.0)
_erf = np.frompyfunc(math.erf, 1, 1)


@dataclass(frozen=True)
class RangeModelParams:
    """The range finder's model, with AMCL's (nav2's) parameter names and defaults.

    Attributes
    ----------
    z_hit, z_short, z_max, z_rand : float
        Mixture weights (>= 0, not all zero; divided by their sum).
    sigma_hit : float
        Std of the hit part [m], > 0.
    lambda_short : float
        Rate of the short part [1/m], > 0.
    laser_max_range : float
        z_max [m], > 0.
    laser_likelihood_max_dist : float
        Cap on the likelihood field's distance [m], > 0.
    """

    z_hit: float = 0.5
    z_short: float = 0.05
    z_max: float = 0.05
    z_rand: float = 0.5
    sigma_hit: float = 0.2
    lambda_short: float = 0.1
    laser_max_range: float = 100.0
    laser_likelihood_max_dist: float = 2.0

    def __post_init__(self) -> None:
        for name in ("z_hit", "z_short", "z_max", "z_rand"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise UsageError(f"range model: {name} must be a number >= 0, got {v!r}")
        if self.z_hit + self.z_short + self.z_max + self.z_rand <= 0:
            raise UsageError("range model: z_hit + z_short + z_max + z_rand must be > 0")
        for name in ("sigma_hit", "lambda_short", "laser_max_range", "laser_likelihood_max_dist"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise UsageError(f"range model: {name} must be a number > 0, got {v!r}")

    @property
    def weights(self) -> np.ndarray:
        """(z_hit, z_short, z_max, z_rand) divided by their sum, shape (4,)."""
        w = np.array([self.z_hit, self.z_short, self.z_max, self.z_rand], dtype=float)
        return w / w.sum()


def _phi(x: np.ndarray) -> np.ndarray:
    """Standard normal CDF (math.erf per element: exact, used only where it is not 0 or 1)."""
    return 0.5 * (1.0 + np.asarray(_erf(np.asarray(x, dtype=float) / _SQRT2), dtype=float))


def hit_mass(z_star, params: RangeModelParams) -> np.ndarray:
    """eta: the mass of N(z*, sigma_hit^2) on [0, z_max], same shape as ``z_star``."""
    z_star = np.asarray(z_star, dtype=float)
    s, z_max = params.sigma_hit, params.laser_max_range
    eta = np.ones_like(z_star)
    # Away from both ends (> 9 sigma) the mass is 1 to double precision: erf only near them.
    near = (z_star < 9 * s) | (z_max - z_star < 9 * s)
    if near.any():
        zs = z_star[near]
        eta[near] = _phi((z_max - zs) / s) - _phi(-zs / s)
    return eta


def beam_density(z, z_star, params: RangeModelParams) -> np.ndarray:
    """p(z | z*) of the beam model, broadcast over ``z`` and ``z_star`` [m].

    Readings >= z_max count as z_max (the point mass, with value 1 as in Thrun and AMCL).
    """
    z, z_star = np.broadcast_arrays(np.asarray(z, dtype=float), np.asarray(z_star, dtype=float))
    w_hit, w_short, w_max, w_rand = params.weights
    s, lam, z_max = params.sigma_hit, params.lambda_short, params.laser_max_range
    z = np.minimum(z, z_max)
    zs = np.clip(z_star, 0.0, z_max)
    valid = z >= 0
    p_hit = np.exp(-0.5 * ((z - zs) / s) ** 2) / (s * math.sqrt(2 * math.pi) * hit_mass(zs, params))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        p_short = np.where(zs > 0, lam * np.exp(-lam * z) / -np.expm1(-lam * zs), 0.0)
    p_short = np.where(z <= zs, p_short, 0.0)
    p_short = np.where((zs == 0) & (z == 0), 1.0, p_short)
    p_max = (z >= z_max).astype(float)
    p_rand = np.where(z < z_max, 1.0 / z_max, 0.0)
    p = w_hit * p_hit + w_short * p_short + w_max * p_max + w_rand * p_rand
    return np.where(valid, p, 0.0)


def sample_beam(z_star, params: RangeModelParams, rng: np.random.Generator) -> np.ndarray:
    """Readings [m] drawn from p(z | z*), one per element of ``z_star``, using only ``rng``."""
    z_star = np.clip(np.asarray(z_star, dtype=float), 0.0, params.laser_max_range)
    shape = z_star.shape
    zs = z_star.ravel()
    n = zs.size
    s, lam, z_max = params.sigma_hit, params.lambda_short, params.laser_max_range
    part = rng.choice(4, size=n, p=params.weights)
    u = rng.random(n)
    out = np.empty(n)
    # hit: N(z*, s^2) truncated to [0, z_max], by redrawing what falls outside.
    hit = np.flatnonzero(part == 0)
    draw = rng.normal(zs[hit], s)
    bad = np.flatnonzero((draw < 0) | (draw > z_max))
    while bad.size:
        draw[bad] = rng.normal(zs[hit[bad]], s)
        bad = bad[(draw[bad] < 0) | (draw[bad] > z_max)]
    out[hit] = draw
    # short: inverse CDF of the exponential truncated to [0, z*].
    short = part == 1
    out[short] = -pm.log1p(u[short] * pm.expm1(-lam * zs[short])) / lam   # portable: readings
    out[part == 2] = z_max
    rand = part == 3
    out[rand] = u[rand] * z_max
    return out.reshape(shape)


def log_beam_likelihood(z, z_star, params: RangeModelParams) -> np.ndarray:
    """Sum over the last axis of log p(z | z*): e.g. ``z`` (n_beams,), ``z_star``
    (n_particles, n_beams) -> (n_particles,)."""
    with np.errstate(divide="ignore"):
        return np.log(beam_density(z, z_star, params)).sum(axis=-1)


# --------------------------------------------------------------------------- likelihood field


#: The smallest map [cells] whose distance transform goes to scipy (500 x 500: numpy takes
#: ~0.3 s there, importing scipy.ndimage ~0.8 s the first time).
SCIPY_MIN_CELLS = 250_000


def distance_transform(occupied: np.ndarray, max_distance: float | None = None) -> np.ndarray:
    """Exact Euclidean distance [cells] from each cell centre to the nearest occupied cell
    centre, shape of ``occupied`` (rows, cols); ``inf`` everywhere when none is occupied;
    with ``max_distance`` [cells], ``min(distance, max_distance)``.

    On a map of :data:`SCIPY_MIN_CELLS` cells or more, scipy's
    ``ndimage.distance_transform_edt`` when scipy is installed (the ``science`` extra; 2-40x
    faster there: benchmarks/bench_scipy_paths.py), :func:`distance_transform_numpy`
    otherwise (on a small map numpy takes less than importing scipy). Both are exact: each
    distance is the square root of the same integer sum of squares, so the results are equal
    bit for bit (tests/core/test_scipy_paths.py) and a run is the same with or without scipy.
    """
    occ = np.asarray(occupied, dtype=bool)
    ndimage = optional("scipy.ndimage") if occ.size >= SCIPY_MIN_CELLS else None
    if ndimage is None:
        return distance_transform_numpy(occ, max_distance)
    cap = np.inf if max_distance is None else float(max_distance)
    if not occ.any():
        return np.full(occ.shape, cap)
    d = ndimage.distance_transform_edt(~occ)
    return np.minimum(np.asarray(d, dtype=float), cap)


def distance_transform_numpy(occupied: np.ndarray, max_distance: float | None = None) -> np.ndarray:
    """:func:`distance_transform` in numpy alone (the base install's).

    Two passes (the separable form of Felzenszwalb and Huttenlocher's transform): the
    distance to the nearest occupied cell in the same column, g, by running maxima of
    indices; then D^2(r, c) = min over c' of (c - c')^2 + g(r, c')^2, taking offsets
    |c - c'| = 0, 1, 2, ... until the offset alone exceeds every distance found.

    With ``max_distance`` [cells] the result is ``min(distance, max_distance)``, still exact
    below the cap, and the second pass stops at that offset (the likelihood field needs no
    more; an open 4096 x 4096 map would otherwise take thousands of passes).
    """
    occ = np.asarray(occupied, dtype=bool)
    rows, cols = occ.shape
    cap = np.inf if max_distance is None else float(max_distance)
    if not occ.any():
        return np.full(occ.shape, cap)
    r = np.arange(rows, dtype=float)[:, None]
    above = np.where(occ, r, -np.inf)
    np.maximum.accumulate(above, axis=0, out=above)          # last occupied row <= r
    below = np.where(occ, r, np.inf)[::-1]
    np.minimum.accumulate(below, axis=0, out=below)          # first occupied row >= r
    below = below[::-1]
    g2 = np.minimum(r - above, below - r) ** 2               # column-wise squared distance
    d2 = g2.copy()
    for off in range(1, cols):
        if off * off >= d2.max() or off > cap:
            break
        np.minimum(d2[:, off:], g2[:, :-off] + off * off, out=d2[:, off:])
        np.minimum(d2[:, :-off], g2[:, off:] + off * off, out=d2[:, :-off])
    return np.minimum(np.sqrt(d2), cap)


@dataclass(frozen=True)
class LikelihoodField:
    """The likelihood-field model of one map, precomputed once.

    Attributes
    ----------
    grid : OccupancyGrid
    params : RangeModelParams
    """

    grid: OccupancyGrid
    params: RangeModelParams

    def __getstate__(self) -> dict:
        return {k: v for k, v in self.__dict__.items() if k in self.__dataclass_fields__}

    @cached_property
    def distance(self) -> np.ndarray:
        """Distance [m] of each cell centre to the nearest occupied cell, capped at
        ``laser_likelihood_max_dist``, shape grid.shape, float64."""
        cap = self.params.laser_likelihood_max_dist
        d = distance_transform(self.grid.occupied, cap / self.grid.resolution) * self.grid.resolution
        return np.minimum(d, cap)

    def beam_probability(self, d) -> np.ndarray:
        """z_hit N(d; 0, sigma_hit^2) + z_rand / z_max for distances ``d`` [m] (Table 6.3)."""
        p = self.params
        w_hit, _, _, w_rand = p.weights
        d = np.asarray(d, dtype=float)
        return (w_hit * np.exp(-0.5 * (d / p.sigma_hit) ** 2) / (p.sigma_hit * math.sqrt(2 * math.pi))
                + w_rand / p.laser_max_range)

    #: Cells of border around the table, holding the off-map value: end points are clipped
    #: into it (a small table stays in cache; a border as wide as the range would not).
    _padding = 1

    @cached_property
    def _log_table(self) -> dict:
        """log beam_probability per cell, padded with the off-map value, float64 and float32."""
        pad = self._padding
        rows, cols = self.grid.shape
        off_map = float(np.log(self.beam_probability(self.params.laser_likelihood_max_dist)))
        table = np.full((rows + 2 * pad, cols + 2 * pad), off_map)
        table[pad:pad + rows, pad:pad + cols] = np.log(self.beam_probability(self.distance))
        return {np.float64: table.ravel(), np.float32: table.astype(np.float32).ravel(),
                "width": cols + 2 * pad, "height": rows + 2 * pad, "off_map": off_map}

    def log_likelihood(self, poses, ranges, rel_angles, *, dtype=np.float64) -> np.ndarray:
        """log p(scan | pose) per pose: the sum over beams below z_max of log(z_hit N(d; 0,
        sigma_hit^2) + z_rand / z_max), the sensor at the robot's centre.

        Parameters
        ----------
        poses : ndarray, shape (n, 3) [m, m, rad]
            World poses (e.g. particles).
        ranges, rel_angles : ndarray, shape (b,) [m], [rad]
            The scan: readings and beam headings relative to the robot.
        dtype : np.float64 or np.float32
            The precision of the end points (float32 is faster; tests hold it to float64).

        Returns
        -------
        ndarray, shape (n,)
        """
        return self._table_sum(self._log_table, poses, ranges, rel_angles, dtype)

    @cached_property
    def _amcl_table(self) -> dict:
        """AMCL's per-beam score pz^3 per cell, padded like ``_log_table``."""
        pad = self._padding
        rows, cols = self.grid.shape
        p = self.params

        def cube(d):
            pz = p.z_hit * np.exp(-0.5 * (np.asarray(d) / p.sigma_hit) ** 2) + p.z_rand / p.laser_max_range
            return pz ** 3

        off_map = float(cube(p.laser_likelihood_max_dist))
        table = np.full((rows + 2 * pad, cols + 2 * pad), off_map)
        table[pad:pad + rows, pad:pad + cols] = cube(self.distance)
        return {np.float64: table.ravel(), np.float32: table.astype(np.float32).ravel(),
                "width": cols + 2 * pad, "height": rows + 2 * pad, "off_map": off_map}

    def amcl_log_weight(self, poses, ranges, rel_angles, *, dtype=np.float64) -> np.ndarray:
        """log of ROS AMCL's (and Beluga's) ad hoc likelihood-field weight per pose:
        ``1 + sum over beams below z_max of pz^3``, ``pz = z_hit exp(-d^2 / (2 sigma_hit^2))
        + z_rand / z_max`` with the weights as given (not normalised). Far less peaked than
        the product of :meth:`log_likelihood`: a scan of B beams changes a weight by at most
        1 + B, so clouds on look-alike places survive many scans. Shapes as log_likelihood."""
        return np.log1p(self._table_sum(self._amcl_table, poses, ranges, rel_angles, dtype))

    def _table_sum(self, tables: dict, poses, ranges, rel_angles, dtype) -> np.ndarray:
        """Sum over the beams below z_max of ``tables`` at their end points, per pose."""
        dtype = np.float32 if dtype in (np.float32, "float32") else np.float64
        poses = np.asarray(poses, dtype=float).reshape(-1, 3)
        ranges = np.asarray(ranges, dtype=float).ravel()
        rel = np.asarray(rel_angles, dtype=float).ravel()
        use = (ranges < self.params.laser_max_range) & (ranges >= 0) & np.isfinite(ranges)
        z, a = ranges[use], rel[use]
        # Everything in the padded grid's frame [cells]: the pose's position, its heading
        # relative to the grid's axes, the end points in the robot frame.
        uv = self.grid.world_to_grid(poses[:, :2])
        heading = poses[:, 2] - self.grid.origin[2]
        ex = z * np.cos(a) / self.grid.resolution
        ey = z * np.sin(a) / self.grid.resolution
        return self._sum_table(uv, heading, ex, ey, tables[dtype], tables["width"], tables["height"],
                               self._padding, dtype)

    #: Poses scored per block: the block's work arrays (a few hundred kB) are allocated once
    #: and reused, so no call page-faults on fresh memory and the arrays stay in cache.
    _BLOCK_POSES = 2048

    @cached_property
    def _work(self) -> dict:
        """Reusable work arrays, keyed by (number of beams, dtype). Not thread-safe: give each
        thread its own field."""
        return {}

    def _sum_table(self, uv, heading, ex, ey, table, width, height, pad, dtype) -> np.ndarray:
        """Sum over beams of the padded table at the end points (clipped into the border)."""
        n, b = len(uv), len(ex)
        out = np.empty(n)
        if b == 0:
            out[:] = 0.0
            return out
        key = (b, dtype)
        if key not in self._work:
            m = self._BLOCK_POSES
            self._work[key] = (np.empty((m, b), dtype), np.empty((m, b), dtype), np.empty((m, b), dtype),
                               np.empty((m, b), np.int32), np.empty((m, b), np.int32),
                               np.empty((m, b), table.dtype))
        col_w, row_w, tmp_w, idx_w, idx2_w, val_w = self._work[key]
        u = (uv[:, 0] + pad).astype(dtype)
        v = (uv[:, 1] + pad).astype(dtype)
        c, s = np.cos(heading).astype(dtype), np.sin(heading).astype(dtype)
        ex, ey = ex.astype(dtype), ey.astype(dtype)
        for start in range(0, n, self._BLOCK_POSES):
            stop = min(start + self._BLOCK_POSES, n)
            m = stop - start
            col, row, tmp, idx, idx2, val = (w[:m] for w in (col_w, row_w, tmp_w, idx_w, idx2_w, val_w))
            cb, sb = c[start:stop, None], s[start:stop, None]
            # end point = position + R(heading) e [cells], then clipped into [0, size - 1]:
            # the border cells hold the off-map value, and after clipping truncation is floor.
            np.multiply(cb, ex, out=col)
            np.multiply(sb, ey, out=tmp)
            col -= tmp
            col += u[start:stop, None]
            np.clip(col, 0, width - 1, out=col)
            np.multiply(sb, ex, out=row)
            np.multiply(cb, ey, out=tmp)
            row += tmp
            row += v[start:stop, None]
            np.clip(row, 0, height - 1, out=row)
            idx[...] = row           # truncation toward zero: floor, the values being >= 0
            idx *= width
            idx2[...] = col
            idx += idx2
            table.take(idx, out=val)
            val.sum(axis=1, dtype=np.float64, out=out[start:stop])
        return out
