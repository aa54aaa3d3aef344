"""Scan-based Monte Carlo localization on an occupancy grid, as ROS AMCL does it.

A particle filter whose measurement is a laser scan (a ``range_finder`` sensor, docs/maps.md),
with the parameter names of ROS amcl (nav2 drops the ``laser_`` prefix of some) so that its
users recognise them:

- A world without walls is an open grid over its bounds: nothing to see, only the motion
  model (mcl reads range_finder scans only; beacon readings are for the other filters).
- Start: a Gaussian around a pose (tracking), or uniform over the map's *free* cells and all
  headings (global localization, AMCL's ``global_localization`` service).
- Motion: every particle executes the command with its own noise, drawn from the scenario's
  motion model (the one the filter is told), times the map prior (Probabilistic Robotics
  sec. 5.6): a move that would end in a wall, an unknown cell or off the map is drawn again
  (AMCL lets particles walk through walls and leaves them to the scan, which with its
  ``1 + sum pz^3`` weights barely penalises them: 7 % of the symmetric room's global cloud
  stood outside its walls after 2.5 s).
- Measurement: ``laser_model_type`` ``likelihood_field`` (Probabilistic Robotics table 6.3,
  the distance transform precomputed once: ``core/beam_model.LikelihoodField``), its beams
  combined as AMCL and Beluga do (``beam_combination = "amcl"``: weight ``1 + sum pz^3``,
  gentle enough that look-alike places keep their clouds) or as Thrun's product of
  densities (``"product"``: sharper, and a cloud on one of two look-alike places dies
  within a few scans by chance alone), or ``beam``
  (eq. 6.12, every beam ray cast from every particle: ~40 times dearer), on
  ``laser_max_beams`` beams taken evenly from the scan (AMCL's subsampling). Readings at
  max range are skipped by the likelihood field, as in AMCL; a particle inside a wall (or
  off the map) scores as if every beam ended off the map, the least a scan can score.
- Recovery: augmented MCL (table 8.3): ``w_slow`` and ``w_fast`` follow the average
  weight of a scan at rates ``recovery_alpha_slow`` / ``recovery_alpha_fast``; each
  resampling replaces a share ``max(0, 1 - w_fast / w_slow)`` of the particles by random
  free poses. AMCL's weights are averaged as they are; a product of densities is taken per
  beam (its geometric mean over the beams used), so that 60 beams do not underflow.
- Resampling: after every ``resample_interval``-th update. KLD-sampling (Fox 2003, AMCL's
  ``pf_err`` / ``pf_z``, here ``kld_err`` / ``kld_z``) sets the new count between
  ``min_particles`` and ``max_particles``: draws in random order until the count reaches the
  KLD bound for the histogram bins (``kld_bin_xy`` [m] x ``kld_bin_theta`` [rad]) occupied.
  As in AMCL's code, ``kld_z`` is used as the normal quantile itself (its default, 0.99,
  is the one AMCL ships).
- Updates only after the robot moved ``update_min_d`` [m] or turned ``update_min_a`` [rad]
  since the last one (AMCL's defaults 0.2 m / 0.5 rad; 0 here: every scan).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.beam_model import LikelihoodField, RangeModelParams, log_beam_likelihood
from beacon_sim.core.occupancy import OccupancyGrid
from beacon_sim.core.raycast import expected_ranges
from beacon_sim.core.sensor_kinds import is_scan
from beacon_sim.core.types import Control, Measurement
from beacon_sim.filters.base import FilterBase, FilterContext, FilterError, GaussianBelief, ParticleBelief
from beacon_sim.filters.particle.pf import weighted_pose_stats
from beacon_sim.filters.resampling import RESAMPLERS, effective_sample_size, resample

LASER_MODELS = ("likelihood_field", "beam")

#: Draws of a particle's motion noise before a move that keeps ending outside free space is
#: given up (the map prior in ``predict``).
MOTION_TRIES = 10


#: Least roughening std [m, m, rad] of a collapsed cloud (:meth:`MonteCarloLocalization._keep_diversity`).
ROUGHENING_FLOOR = np.array([0.01, 0.01, 0.005])


def subsample_beams(n_beams: int, max_beams: int) -> np.ndarray:
    """Indices of at most ``max_beams`` beams spread evenly over ``n_beams`` (the first and
    the last included), as AMCL's ``laser_max_beams`` picks them."""
    if max_beams >= n_beams or n_beams <= 1:
        return np.arange(n_beams)
    if max_beams <= 1:
        return np.zeros(1, dtype=int)
    return np.unique(np.round(np.linspace(0, n_beams - 1, max_beams)).astype(int))


def open_grid(bounds: tuple[float, float, float, float]) -> OccupancyGrid:
    """An all-free grid over ``bounds`` [m] (at most 1000 cells a side): the map of a world
    without walls, where mcl has nothing to see and runs on its motion model alone."""
    xmin, ymin, xmax, ymax = bounds
    res = max(0.1, (xmax - xmin) / 1000, (ymax - ymin) / 1000)
    shape = (max(1, math.ceil((ymax - ymin) / res)), max(1, math.ceil((xmax - xmin) / res)))
    return OccupancyGrid(np.zeros(shape, dtype=np.int8), res, (xmin, ymin, 0.0))


def kld_bound(bins: np.ndarray, err: float, z: float) -> np.ndarray:
    """The KLD-sampling count (Fox 2003) for ``bins`` occupied histogram bins: the number of
    samples after which the sample-based posterior is within ``err`` (KL divergence) of the
    true one with the confidence ``z`` stands for. 1 for a single bin."""
    k1 = np.maximum(np.asarray(bins, dtype=np.float64) - 1.0, 1.0)
    a = 2.0 / (9.0 * k1)
    need = k1 / (2.0 * err) * (1.0 - a + np.sqrt(a) * z) ** 3
    return np.where(np.asarray(bins) <= 1, 1.0, np.ceil(need))


class MonteCarloLocalization(FilterBase):
    """AMCL on the world's occupancy grid. Attributes for the HUD: ``n`` (particles),
    ``w_slow``, ``w_fast``, ``inject_prob``, ``ess``."""

    supports_global = True
    defaults: ClassVar[dict[str, Any]] = {
        "min_particles": 500,              # KLD-sampling's fewest particles (AMCL: 500)
        "max_particles": 5000,             # its most, and the count after a global reset
        "kld_err": 0.01,                   # AMCL's pf_err
        "kld_z": 0.99,                     # AMCL's pf_z (used as the quantile, as AMCL does)
        "kld_bin_xy": 0.5,                 # KLD histogram bin [m] (AMCL's)
        "kld_bin_theta": math.radians(10),  # KLD histogram bin [rad] (AMCL's)
        "recovery_alpha_slow": 0.001,      # AMCL's suggested values (its defaults, 0, turn
        "recovery_alpha_fast": 0.1,        #   recovery off)
        "resample_interval": 1,            # resample after every n-th update
        "selective_resampling": False,     # AMCL's: ... and only when ESS < n / 2
        "resampler": "multinomial",        # which particles: systematic | stratified |
                                           #   residual | multinomial (filters/resampling.py)
        "update_min_d": 0.0,               # [m] update only after moving this far ...
        "update_min_a": 0.0,               # [rad] ... or turning this much
        "laser_model_type": "likelihood_field",  # likelihood_field | beam
        "beam_combination": "amcl",        # likelihood field: amcl (1 + sum pz^3) | product
        "laser_max_beams": 60,             # beams used per scan (nav2's default)
        "laser_z_hit": 0.5,
        "laser_z_short": 0.05,
        "laser_z_max": 0.05,
        "laser_z_rand": 0.5,
        "laser_sigma_hit": 0.2,            # [m]
        "laser_lambda_short": 0.1,         # [1/m]
        "laser_likelihood_max_dist": 2.0,  # [m] the likelihood field's distance cap
        "laser_max_range": -1.0,           # [m]; -1: the sensor's max_range (AMCL's meaning)
        "dtype": "float32",                # likelihood field's end points: float32 | float64
        "min_distinct": 0.05,              # roughening below this share of distinct poses
        "blocked_motion_weight": 1.0,      # weight factor of a particle whose move the map
                                           #   blocks (every draw into a wall); AMCL: 1
    }

    def __init__(self, ctx: FilterContext):
        super().__init__(ctx)
        p = self.params
        if p["laser_model_type"] not in LASER_MODELS:
            raise FilterError(f"mcl: laser_model_type {p['laser_model_type']!r}: use "
                              f"{' or '.join(LASER_MODELS)}")
        if p["beam_combination"] not in ("amcl", "product"):
            raise FilterError(f"mcl: beam_combination {p['beam_combination']!r}: use amcl or product")
        if p["dtype"] not in ("float32", "float64"):
            raise FilterError(f"mcl: dtype {p['dtype']!r}: use float32 or float64")
        if not 1 <= int(p["min_particles"]) <= int(p["max_particles"]):
            raise FilterError("mcl: need 1 <= min_particles <= max_particles")
        if p["resampler"] not in RESAMPLERS:
            raise FilterError(f"mcl: resampler {p['resampler']!r}: use {' | '.join(RESAMPLERS)}")
        if not isinstance(p["selective_resampling"], bool):
            raise FilterError(f"mcl: selective_resampling = {p['selective_resampling']!r}: "
                              "expected true or false")
        if int(p["laser_max_beams"]) < 1 or int(p["resample_interval"]) < 1:
            raise FilterError("mcl: laser_max_beams and resample_interval must be >= 1")
        for key in ("recovery_alpha_slow", "recovery_alpha_fast"):
            if not 0.0 <= p[key] <= 1.0:
                raise FilterError(f"mcl: {key} = {p[key]!r}: expected a rate in [0, 1]")
        if not (p["kld_err"] > 0 and p["kld_bin_xy"] > 0 and p["kld_bin_theta"] > 0):
            raise FilterError("mcl: kld_err, kld_bin_xy and kld_bin_theta must be > 0")
        self.grid = ctx.world.grid if ctx.world.grid is not None else open_grid(ctx.world.bounds)
        self._walls = ctx.world.grid is not None
        self._models: dict[float, tuple[RangeModelParams, LikelihoodField | None]] = {}
        cols = self.grid.shape[1]
        free = np.flatnonzero(self.grid.cells.ravel() == 0)
        if free.size == 0:
            raise FilterError("mcl: the map has no free cell")
        self._free_cells = free
        self._is_free = self.grid.cells.reshape(-1) == 0  # per cell, row by row (in_free_space)
        self._cols = cols
        self.n = 0
        self.poses = np.zeros((0, 3))
        self.logw = np.zeros(0)
        self.w_slow = self.w_fast = 0.0
        self.inject_prob = 0.0
        self.ess = 0.0
        self._updates = 0
        self._moved = (0.0, 0.0)
        self._cache: tuple[np.ndarray, np.ndarray] | None = None
        self.reset(None)

    # ----------------------------------------------------------------- models
    def model(self, sensor_max_range: float) -> tuple[RangeModelParams, LikelihoodField | None]:
        """The range model (and likelihood field) for a sensor of this max range [m]."""
        if sensor_max_range not in self._models:
            p = self.params
            z_max = p["laser_max_range"] if p["laser_max_range"] > 0 else sensor_max_range
            params = RangeModelParams(
                z_hit=p["laser_z_hit"], z_short=p["laser_z_short"], z_max=p["laser_z_max"],
                z_rand=p["laser_z_rand"], sigma_hit=p["laser_sigma_hit"],
                lambda_short=p["laser_lambda_short"], laser_max_range=z_max,
                laser_likelihood_max_dist=p["laser_likelihood_max_dist"])
            field = LikelihoodField(self.grid, params) if p["laser_model_type"] == "likelihood_field" \
                else None
            self._models[sensor_max_range] = (params, field)
        return self._models[sensor_max_range]

    def random_free_poses(self, n: int) -> np.ndarray:
        """``n`` poses uniform over the map's free cells and all headings, shape (n, 3)."""
        rng = self.ctx.rng
        cells = self._free_cells[rng.integers(0, self._free_cells.size, n)]
        rc = np.stack([cells // self._cols, cells % self._cols], axis=1).astype(float)
        uv = np.stack([rc[:, 1] + rng.random(n), rc[:, 0] + rng.random(n)], axis=1)
        xy = self.grid.grid_to_world(uv)
        return np.column_stack([xy, rng.uniform(-math.pi, math.pi, n)])

    # ----------------------------------------------------------------- belief
    def reset(self, initial: GaussianBelief | None) -> None:
        """Gaussian ``initial`` (tracking, ``min_particles``... ``max_particles``: the
        KLD count of the cloud) or None: ``max_particles`` uniform over the free cells."""
        rng = self.ctx.rng
        n_max = int(self.params["max_particles"])
        if initial is None:
            P = self.random_free_poses(n_max)
        else:
            cov = np.asarray(initial.cov, dtype=float)
            L = np.linalg.cholesky(0.5 * (cov + cov.T) + 1e-12 * np.eye(3))
            P = np.asarray(initial.mean, dtype=float)[None, :] + rng.standard_normal((n_max, 3)) @ L.T
            P[:, 2] = wrap(P[:, 2])
        self._set(P)
        self.w_slow = self.w_fast = 0.0
        self.inject_prob = 0.0
        self._updates = 0
        self._moved = (0.0, 0.0)

    def _set(self, P: np.ndarray) -> None:
        self.poses = P
        self.n = len(P)
        self.logw = np.full(self.n, -math.log(self.n))
        self.ess = float(self.n)
        self._cache = None

    def weights(self) -> np.ndarray:
        """Normalised weights, shape (n,)."""
        w = np.exp(self.logw - self.logw.max())
        return w / w.sum()

    def estimate(self) -> tuple[np.ndarray, np.ndarray]:
        """Weighted mean and covariance ([m, m, rad]; circular heading)."""
        if self._cache is None:
            self._cache = weighted_pose_stats(np.ascontiguousarray(self.poses.T), self.weights())
        mean, cov = self._cache
        return mean.copy(), cov.copy()

    def belief(self) -> ParticleBelief:
        return ParticleBelief(self.poses.copy(), self.weights())

    # ----------------------------------------------------------------- motion
    def predict(self, control: Control, dt: float) -> None:
        """Every particle moves with its own noisy copy of the command (velocity model); in
        a world with walls, a move that would end outside the map's free space is drawn
        again (the map prior, below)."""
        old = self.poses
        P = self._moved_poses(old, control, dt)
        if self._walls:
            # The map-based motion model (Probabilistic Robotics sec. 5.6): p(x' | u, x, m)
            # is p(x' | u, x) times the prior that the robot is in free space, zero in a
            # wall, in an unknown cell or off the map. Sampled by rejection: a particle
            # whose move ends there draws its noise again, up to ``MOTION_TRIES`` times;
            # one that still finds no free pose stays where it was (the robot's bumper
            # stops it too), or, if it was not in free space either, keeps its last draw.
            bad = np.flatnonzero(~self.in_free_space(P))
            for _ in range(MOTION_TRIES):
                if bad.size == 0:
                    break
                P[bad] = self._moved_poses(old[bad], control, dt)
                bad = bad[~self.in_free_space(P[bad])]
            if bad.size:
                stay = bad[self.in_free_space(old[bad])]
                P[stay] = old[stay]
                # A particle none of whose draws moved it: the odometry says the robot moved,
                # which from there it could not (AMCL keeps its weight: 1.0).
                blocked = float(self.params["blocked_motion_weight"])
                if blocked != 1.0:
                    self.logw = self.logw.copy()
                    self.logw[bad] += math.log(blocked)
        self.poses = P
        self.n = len(P)
        md, ma = self._moved
        self._moved = (md + abs(control.v) * dt, ma + abs(control.omega) * dt)
        self._cache = None

    def _moved_poses(self, P: np.ndarray, control: Control, dt: float) -> np.ndarray:
        """New poses (n, 3) of particles ``P`` after the command, each with its own noise."""
        n, rng = len(P), self.ctx.rng
        noise = self.ctx.motion_noise
        sv, sw = noise.control_std(control.v, control.omega)
        d = (control.v + sv * rng.standard_normal(n)) * dt
        a = (control.omega + sw * rng.standard_normal(n)) * dt
        Q = P.copy()
        Q[:, 0] += d * np.cos(P[:, 2])
        Q[:, 1] += d * np.sin(P[:, 2])
        Q[:, 2] += a
        ps = noise.pose_std_at(control.v, control.omega)
        if any(ps):
            Q += rng.standard_normal((n, 3)) * np.asarray(ps)
        Q[:, 2] = wrap(Q[:, 2])
        return Q

    # ----------------------------------------------------------------- measurement
    def scan_log_likelihood(self, m: Measurement) -> tuple[np.ndarray, int]:
        """log p(scan | particle), shape (n,), and the number of beams it used."""
        spec = self.ctx.sensor(m.sensor)
        params, field = self.model(spec.max_range)
        idx = subsample_beams(len(m), int(self.params["laser_max_beams"]))
        ranges, rel = m.z[idx, 0], m.z[idx, 1]
        if field is not None:
            dtype = np.float32 if self.params["dtype"] == "float32" else np.float64
            used = int(np.count_nonzero(ranges < params.laser_max_range))
            amcl = self.params["beam_combination"] == "amcl"
            if amcl:
                ll = field.amcl_log_weight(self.poses, ranges, rel, dtype=dtype)
            else:
                ll = field.log_likelihood(self.poses, ranges, rel, dtype=dtype)
            # The field knows only where obstacles are, not that the robot cannot be inside
            # one: a particle in a wall scores as if every beam ended off the map (the least
            # a beam can score), so it never outweighs one in free space.
            inside = ~self.in_free_space(self.poses)
            if inside.any():
                ll[inside] = math.log1p(used * field._amcl_table["off_map"]) if amcl \
                    else used * field._log_table["off_map"]
            return ll, used
        expected = expected_ranges(self.grid, self.poses, rel, params.laser_max_range)
        return log_beam_likelihood(ranges, expected, params), len(idx)

    def in_free_space(self, poses: np.ndarray) -> np.ndarray:
        """Whether each pose (n, 3) lies in a free cell of the map (off the map: no).

        The map's cell of each pose as ``OccupancyGrid.world_to_cell`` finds it (the same
        floor of the same grid coordinates), looked up in a flat table of the free cells
        made with the filter (its map never changes): the motion's map prior asks this
        of every particle on every predict, and of the redrawn ones up to ten times more."""
        rows, cols = self.grid.shape
        uv = np.floor(self.grid.world_to_grid(poses[:, :2]))
        u, v = uv[:, 0], uv[:, 1]  # column, row (NaN and any reach off the grid: outside)
        inside = (v >= 0) & (v < rows) & (u >= 0) & (u < cols)
        at = np.clip(v, 0, rows - 1) * cols + np.clip(u, 0, cols - 1)
        return inside & self._is_free[np.nan_to_num(at).astype(np.intp)]

    def update(self, measurements: Sequence[Measurement]) -> None:
        """Weight by every scan of the tick, then (every ``resample_interval`` updates)
        resample with KLD-sampling and augmented-MCL random particles."""
        scans = [m for m in measurements if is_scan(m.kind) and len(m)]
        if not scans:
            return
        p = self.params
        md, ma = self._moved
        if self._updates and md < p["update_min_d"] and ma < p["update_min_a"]:
            return
        self._moved = (0.0, 0.0)
        for m in scans:
            ll, used = self.scan_log_likelihood(m)
            if used == 0:
                continue
            joint = self.logw + ll
            top = float(joint.max())
            if not math.isfinite(top):
                raise FilterError("mcl: every particle has zero likelihood")
            log_total = top + math.log(float(np.exp(joint - top).sum()))   # log sum w_i p_i
            self.logw = joint - log_total
            # AMCL's weights are 1 + sum pz^3: their average as it is; a product of B beams'
            # densities: per beam (its geometric mean), or 60 beams would underflow.
            amcl = self.params["beam_combination"] == "amcl" and \
                self.params["laser_model_type"] == "likelihood_field"
            w_avg = math.exp(log_total if amcl else log_total / used)
            if self.w_slow == 0.0:
                self.w_slow = self.w_fast = w_avg
            else:
                self.w_slow += p["recovery_alpha_slow"] * (w_avg - self.w_slow)
                self.w_fast += p["recovery_alpha_fast"] * (w_avg - self.w_fast)
        self.inject_prob = max(0.0, 1.0 - self.w_fast / self.w_slow) if self.w_slow > 0 else 0.0
        self.ess = effective_sample_size(self.weights())
        self._cache = None
        self._updates += 1
        if self._updates % int(p["resample_interval"]) == 0 \
                and not (p["selective_resampling"] and self.ess >= 0.5 * self.n):
            self._resample()

    def _resample(self) -> None:
        """A new equally weighted set: candidates drawn in random order from the weights (a
        share ``inject_prob`` replaced by random free poses), kept up to the KLD count."""
        p, rng = self.params, self.ctx.rng
        n_max, n_min = int(p["max_particles"]), int(p["min_particles"])
        w = self.weights()
        cand = self.poses[rng.choice(self.n, size=n_max, p=w)]
        mask = np.zeros(n_max, dtype=bool)
        if self.inject_prob > 0:
            mask = rng.random(n_max) < self.inject_prob
            k = int(mask.sum())
            if k:
                cand[mask] = self.random_free_poses(k)
        # KLD: after j draws occupying k_j bins, stop once j >= bound(k_j) (and j >= n_min).
        bxy, bth = p["kld_bin_xy"], p["kld_bin_theta"]
        ix = np.floor(cand[:, 0] / bxy).astype(np.int64)
        iy = np.floor(cand[:, 1] / bxy).astype(np.int64)
        it = np.floor((cand[:, 2] + math.pi) / bth).astype(np.int64)
        key = (ix * 1_000_003 + iy) * 1_009 + it
        _, first = np.unique(key, return_index=True)
        new_bin = np.zeros(n_max, dtype=np.int64)
        new_bin[first] = 1
        bins = np.cumsum(new_bin)
        j = np.arange(1, n_max + 1)
        ok = np.flatnonzero((j >= kld_bound(bins, p["kld_err"], p["kld_z"])) & (j >= n_min))
        count = int(ok[0]) + 1 if ok.size else n_max
        if p["resampler"] == "multinomial":
            self._set(cand[:count].copy())
            self._keep_diversity()
            return
        # The KLD count came from draws in random order (what its bound assumes); which
        # particles make up the new set is then drawn with the lower-variance scheme: the
        # random share as drawn, the rest copies of the old set (a look-alike place's cloud
        # keeps its expected share up to one particle with systematic resampling, where
        # multinomial draws let it drift and die by chance).
        k = int(mask[:count].sum()) if self.inject_prob > 0 else 0
        keep = self.poses[resample(p["resampler"], w, count - k, rng)] if count > k \
            else self.poses[:0]
        self._set(np.concatenate([keep, cand[:count][mask[:count]]]) if k else keep.copy())
        self._keep_diversity()

    def _keep_diversity(self) -> None:
        """Roughening (Gordon, Salmond and Smith 1993) of a cloud that has collapsed: when
        fewer than ``min_distinct`` of the particles are distinct poses (standing still,
        resampling copies the heaviest few until two poses remain: a filter with no spread
        left to track with), every copy after the first of a pose is moved by a normal
        draw of std ``0.2 * spread * n^(-1/3)`` per axis (``spread``: the cloud's range on
        that axis), at least 1 cm and 0.005 rad; a draw that lands outside free space stays
        where it was. A cloud with diversity is left as it was, bit for bit, and draws
        nothing."""
        frac = float(self.params["min_distinct"])
        if frac <= 0.0 or self.n < 2:
            return
        _, first = np.unique(self.poses, axis=0, return_index=True)
        if len(first) >= frac * self.n:
            return
        copies = np.ones(self.n, dtype=bool)
        copies[first] = False
        idx = np.flatnonzero(copies)
        spread = self.poses.max(axis=0) - self.poses.min(axis=0)
        std = np.maximum(0.2 * spread * self.n ** (-1.0 / 3.0), ROUGHENING_FLOOR)
        moved = self.poses[idx] + self.ctx.rng.normal(size=(idx.size, 3)) * std
        moved[:, 2] = wrap(moved[:, 2])
        if self._walls:
            ok = self.in_free_space(moved)
            moved[~ok] = self.poses[idx[~ok]]
        P = self.poses.copy()
        P[idx] = moved
        self.poses = P
        self._cache = None


__all__ = [
    "LASER_MODELS", "MOTION_TRIES", "ROUGHENING_FLOOR", "MonteCarloLocalization", "kld_bound",
    "open_grid", "subsample_beams"
]
