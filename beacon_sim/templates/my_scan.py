"""MyScan: my own scan-based particle filter (Monte Carlo localization) for beacon-sim.

It runs as it is: N particles move with the noisy motion model, are weighted by each laser
scan with the likelihood field of the map (Probabilistic Robotics table 6.3, precomputed by
beacon-sim's core) and resampled after every scan. The TODOs lead towards the built-in
``mcl`` (beacon_sim/filters/particle/mcl.py, ROS AMCL's ideas); the maps and the sensor are in
docs/maps.md, the filter interface in docs/writing-a-filter.md.

Try it (from the folder this file is in):

    beacon-sim check my_scan.py:MyScan --scenario corridor
    beacon-sim play office --filter ./my_scan.py:MyScan --filter mcl
    beacon-sim eval office --filter ./my_scan.py:MyScan --filter mcl --runs 10

Conventions: the pose is [x, y, theta] in metres, metres, radians, world frame (y up,
theta counter-clockwise from +x). A scan's ``m.z`` has one row per beam: [range m, beam
angle relative to the robot rad]; a beam with no wall within range reads the sensor's
max_range. Wrap every angle with beacon_sim.core.angles.wrap.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import ClassVar

import numpy as np

from beacon_sim.api import (
    Control,
    FilterBase,
    FilterContext,
    GaussianBelief,
    LikelihoodField,
    Measurement,
    ParticleBelief,
    RangeModelParams,
    systematic,
    wrap,
)


class MyScan(FilterBase):
    """A particle filter over the pose, weighted by laser scans.

    ``self.ctx`` holds everything the filter may know: ``ctx.world.grid`` (the occupancy
    grid, None in a world without walls), ``ctx.motion_noise``, ``ctx.sensor(name)`` (a
    sensor's ``max_range`` [m], ``n_beams``, ``fov`` [rad]), ``ctx.params`` and
    ``ctx.rng``, the only random generator you may use. It never holds the true pose.
    """

    # Set them from a scenario's [filters.MyScan] table or with --set MyScan.KEY=VALUE.
    defaults: ClassVar[dict] = {
        "n_particles": 1000,
        "max_beams": 30,                 # beams used per scan, spread evenly (AMCL's laser_max_beams)
        "sigma_hit": 0.2,                # [m] the likelihood field's Gaussian
        "z_hit": 0.5,                    # its weight; z_rand the weight of a random reading
        "z_rand": 0.5,
        "likelihood_max_dist": 2.0,      # [m] distances to a wall are capped here
    }

    def __init__(self, ctx: FilterContext):
        super().__init__(ctx)   # stores self.ctx and self.params
        self.grid = ctx.world.grid
        self.fields: dict[float, LikelihoodField] = {}   # one per sensor max_range [m]
        n = int(self.params["n_particles"])
        self.poses = np.zeros((n, 3))
        self.logw = np.full(n, -math.log(n))

    # ------------------------------------------------------------------ belief
    def reset(self, initial: GaussianBelief | None) -> None:
        """A Gaussian ``initial`` (tracking) or None: uniform over the map's free cells and all
        headings (global localization)."""
        n, rng = int(self.params["n_particles"]), self.ctx.rng
        if initial is not None:
            L = np.linalg.cholesky(np.asarray(initial.cov, dtype=float) + 1e-12 * np.eye(3))
            P = np.asarray(initial.mean, dtype=float) + rng.standard_normal((n, 3)) @ L.T
        else:
            P = self.uniform_poses(n)
        P[:, 2] = wrap(P[:, 2])
        self.poses = P
        self.logw = np.full(n, -math.log(n))

    def uniform_poses(self, n: int) -> np.ndarray:
        """``n`` poses uniform over the free cells (over the bounds without a map), (n, 3)."""
        rng = self.ctx.rng
        if self.grid is None:
            xmin, ymin, xmax, ymax = self.ctx.world.bounds
            xy = rng.uniform((xmin, ymin), (xmax, ymax), (n, 2))
        else:
            cols = self.grid.shape[1]
            free = np.flatnonzero(~self.grid.occupied.ravel())
            cells = free[rng.integers(0, free.size, n)]
            uv = np.column_stack([cells % cols + rng.random(n), cells // cols + rng.random(n)])
            xy = self.grid.grid_to_world(uv)    # grid (column, row) units -> world [m]
        return np.column_stack([xy, rng.uniform(-math.pi, math.pi, n)])

    def weights(self) -> np.ndarray:
        """Normalised weights, shape (n,)."""
        w = np.exp(self.logw - self.logw.max())
        return w / w.sum()

    def estimate(self) -> tuple[np.ndarray, np.ndarray]:
        """Weighted mean (3,) [m, m, rad] (circular mean heading) and covariance (3, 3)."""
        w, P = self.weights(), self.poses
        theta = math.atan2(float(w @ np.sin(P[:, 2])), float(w @ np.cos(P[:, 2])))
        mean = np.array([w @ P[:, 0], w @ P[:, 1], theta])
        d = P - mean
        d[:, 2] = wrap(d[:, 2])
        cov = (d * w[:, None]).T @ d
        return mean, 0.5 * (cov + cov.T)

    def belief(self) -> ParticleBelief:
        """The particles, for the window to draw."""
        return ParticleBelief(self.poses.copy(), self.weights())

    # ------------------------------------------------------------------ motion
    def predict(self, control: Control, dt: float) -> None:
        """Every particle drives its own noisy copy of the command (velocity model)."""
        n, rng, noise = len(self.poses), self.ctx.rng, self.ctx.motion_noise
        sv, sw = noise.control_std(control.v, control.omega)   # [m/s], [rad/s]
        d = (control.v + sv * rng.standard_normal(n)) * dt
        a = (control.omega + sw * rng.standard_normal(n)) * dt
        P = self.poses
        P[:, 0] += d * np.cos(P[:, 2])
        P[:, 1] += d * np.sin(P[:, 2])
        P[:, 2] = wrap(P[:, 2] + a)
        ps = noise.pose_std_at(control.v, control.omega)       # extra pose noise, if any
        if any(ps):
            P += rng.standard_normal((n, 3)) * np.asarray(ps)
            P[:, 2] = wrap(P[:, 2])

    # ------------------------------------------------------------------ measurement
    def field(self, max_range: float) -> LikelihoodField:
        """The map's likelihood field for a sensor of this max range [m] (built once)."""
        assert self.grid is not None   # update() weighs scans only on a map
        if max_range not in self.fields:
            p = self.params
            model = RangeModelParams(z_hit=p["z_hit"], z_short=0.0, z_max=0.0, z_rand=p["z_rand"],
                                     sigma_hit=p["sigma_hit"], laser_max_range=max_range,
                                     laser_likelihood_max_dist=p["likelihood_max_dist"])
            self.fields[max_range] = LikelihoodField(self.grid, model)
        return self.fields[max_range]

    def update(self, measurements: Sequence[Measurement]) -> None:
        """Weight the particles by each scan of the tick, then resample."""
        if self.grid is None:          # no walls: a scan says nothing (motion only)
            return
        for m in measurements:
            if m.kind != "range_finder" or len(m) == 0:
                continue              # beacon readings: see docs/writing-a-filter.md
            max_range = self.ctx.sensor(m.sensor).max_range
            keep = np.unique(np.linspace(0, len(m) - 1, int(self.params["max_beams"])).astype(int))
            ranges, angles = m.z[keep, 0], m.z[keep, 1]
            # log p(scan | pose) per particle: each beam's end point looked up in the map's
            # distance-to-the-nearest-wall table; beams at max_range are skipped.
            ll = self.field(max_range).log_likelihood(self.poses, ranges, angles)
            # TODO 1: a particle inside a wall scores like one whose beams all end near walls.
            #   Give it the lowest score (see MonteCarloLocalization.in_free_space in mcl.py).
            logw = self.logw + ll
            self.logw = logw - (logw.max() + math.log(np.exp(logw - logw.max()).sum()))
            # TODO 2: resample only when the effective sample size 1 / sum(w^2) drops below
            #   n / 2: fewer resamplings keep more diversity.
            self.resample()

    def resample(self) -> None:
        """Draw n equally weighted particles in proportion to the weights (systematic).

        TODO 3: augmented MCL (Probabilistic Robotics table 8.3): track the average
        likelihood of a scan with a slow and a fast average and replace a share
        max(0, 1 - w_fast / w_slow) of the particles by self.uniform_poses(k), so the filter
        recovers when the robot is kidnapped. TODO 4: KLD-sampling (a particle count that
        follows the spread of the cloud). mcl.py does both.
        """
        n = len(self.poses)
        idx = systematic(self.weights(), n, self.ctx.rng)
        self.poses = self.poses[idx].copy()
        self.logw = np.full(n, -math.log(n))
