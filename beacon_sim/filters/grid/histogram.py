"""Grid (histogram) Bayes filter over x, y AND heading, vectorised over the whole grid.

The belief is a probability per cell of a regular grid: ``cell`` [m] in x and y over the
world bounds, ``heading_bins`` bins of ``2 pi / heading_bins`` [rad] in heading (0.2 m x
0.2 m x 10 deg over a 10 m x 10 m room: 50 x 50 x 36 = 90,000 cells).

Prediction (seed 004's ``bel_bar(x) = sum p(x | u, x') bel(x')``, done as shift + blur):
each heading slab moves along its own heading. The sub-cell part of the motion is kept in a
per-slab offset [m] and the slab is shifted by whole cells when the offset passes half a
cell, so slow motion is not smeared by interpolation; turning is kept the same way in one
heading offset for the whole grid. The motion noise is accumulated as a variance and applied
as a 3-tap blur (x, y and circular in heading) once it is worth a fraction of a cell. The
walls stop the robot, so mass pushed out of the grid piles up in the border cells.

Update (``bel(x) = eta p(z | x) bel_bar(x)``): the likelihood over the whole grid. Ranges
and fixes depend on x, y only (2-D arrays); bearings enter as ``kappa cos(nu)`` (von Mises,
``kappa = 1 / sigma^2``), and since ``cos(z - alpha + theta) = cos(z - alpha) cos(theta) -
sin(z - alpha) sin(theta)``, all bearing readings of a tick sum into two x-y arrays that
meet the heading axis in one outer product. Noise is inflated by the cell size (the belief
is only known to within a cell). A small uniform floor keeps every cell alive, so the filter
can recover from a kidnap.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.geometry import hdop
from beacon_sim.core.sensor_kinds import model_of
from beacon_sim.core.types import Control, Measurement
from beacon_sim.filters import association
from beacon_sim.filters.base import FilterBase, FilterContext, FilterError, GaussianBelief, GridBelief

TWO_PI = 2.0 * math.pi
#: A likelihood's log below -600 (relative to the peak) is clipped there: exp(-600).
_EXP_CLIP = float(np.exp(np.full(16, -600.0))[0])
#: How far (in log-likelihood) a bound must be below the clip for a whole x row to be taken
#: as clipped; covers the rounding of the bound and of the product at magnitudes ~1e4.
_CLIP_MARGIN = 1e-6


class HistogramFilter(FilterBase):
    """Discrete Bayes filter on an x-y-heading grid."""

    supports_global = True
    defaults: ClassVar[dict[str, Any]] = {
        "cell": 0.2,            # x-y cell size [m]
        "heading_bins": 36,     # heading bins over 2 pi (36: 10 deg)
        "floor": 1e-4,          # share of probability spread uniformly after each update
        "blur_min": 0.05,       # apply the motion blur once its variance reaches this * cell^2
        "grid_noise": 1.0,      # discretisation noise: a cell^2/12 and bin^2/12 of variance per
                                # this many seconds of driving (0: off); see predict()
    }

    def __init__(self, ctx: FilterContext):
        super().__init__(ctx)
        p = self.params
        if p["cell"] <= 0 or int(p["heading_bins"]) < 4:
            raise FilterError("histogram: need cell > 0 and heading_bins >= 4")
        if not 0.0 <= p["floor"] < 1.0:
            raise FilterError("histogram: floor must be in [0, 1)")
        self.cell = float(p["cell"])
        xmin, ymin, xmax, ymax = ctx.world.bounds
        self.origin = (float(xmin), float(ymin))
        self.nx = max(1, math.ceil((xmax - xmin) / self.cell - 1e-9))
        self.ny = max(1, math.ceil((ymax - ymin) / self.cell - 1e-9))
        self.nh = int(p["heading_bins"])
        self.bin = TWO_PI / self.nh
        self.xc = xmin + (np.arange(self.nx) + 0.5) * self.cell     # cell centres [m]
        self.yc = ymin + (np.arange(self.ny) + 0.5) * self.cell
        self.base_th = -math.pi + (np.arange(self.nh) + 0.5) * self.bin
        self._yw = np.stack([np.ones(self.ny), self.yc, self.yc**2], axis=1)   # (ny, 3): 1, y, y^2
        self._yw_sum = self._yw.sum(axis=0)
        # (nx * 3, 6): the row sums (p, p y, p y^2 per x) to p, p x, p x^2, p y, p x y, p y^2
        xw = np.zeros((self.nx, 3, 6))
        xw[:, 0, 0] = 1.0
        xw[:, 0, 1] = self.xc
        xw[:, 0, 2] = self.xc**2
        xw[:, 1, 3] = 1.0
        xw[:, 1, 4] = self.xc
        xw[:, 2, 5] = 1.0
        self._xw = xw.reshape(-1, 6)
        self.grid = np.empty((self.nh, self.nx, self.ny))           # [heading, x, y]
        self.offset = np.zeros((self.nh, 2))     # sub-cell position offset of each slab [m]
        self.phi = 0.0                           # sub-bin heading offset of the whole grid [rad]
        self._trig_phi = math.nan                # phi of _trig_cache (theta, sin, cos)
        self._dir_phi = math.nan                 # phi of _dir: cos, sin of base_th + phi
        self._dir: tuple[np.ndarray, np.ndarray] = (self.base_th, self.base_th)
        self._trig_cache: tuple[np.ndarray, np.ndarray, np.ndarray] = (self.base_th,) * 3
        self.var_xy = 0.0                        # motion variance not yet blurred [m^2]
        self.var_th = 0.0                        # [rad^2]
        # Beacon geometry on the x-y grid (the grid never moves): range, cos/sin of direction.
        bxy = ctx.world.beacon_xy
        dx = bxy[:, 0, None, None] - self.xc[None, :, None]
        dy = bxy[:, 1, None, None] - self.yc[None, None, :]
        self._r = np.hypot(dx, dy)                                  # (nb, nx, ny)
        rr = np.maximum(self._r, 1e-9)
        self._ca = dx / rr
        self._sa = dy / rr
        self._hdop_cache: dict[tuple[tuple[int, ...], float], np.ndarray] = {}
        self._basis: dict[tuple[str, float, int], np.ndarray] = {}   # see _beacon_basis
        self._L = np.empty_like(self.grid)      # scratch grids: the likelihood, the blur's
        self._T = np.empty_like(self.grid)      # neighbour sums, a rolled grid (no allocation)
        self._A = np.empty((3, self.nx * self.ny))  # the update's C, S, lxy (x-y arrays) as rows
        self._cache: tuple[np.ndarray, np.ndarray] | None = None
        #: Per (heading, x) row of the grid the sums of p, p y, p y^2, shape (nh, nx, 3), while
        #: they hold for ``grid`` (None: ``_moments`` takes them in one pass).
        self._rows: np.ndarray | None = None
        self.reset(None)

    @property
    def theta(self) -> np.ndarray:
        """Heading of each bin's centre [rad], shape (nh,)."""
        return wrap(self.base_th + self.phi)

    # ----------------------------------------------------------------- initial belief
    def reset(self, initial: GaussianBelief | None) -> None:
        """Uniform over the grid (None) or a Gaussian evaluated at the cell centres."""
        self.offset[:] = 0.0
        self.phi = 0.0
        self.var_xy = self.var_th = 0.0
        if initial is None:
            self.grid.fill(1.0 / self.grid.size)
        else:
            mean = np.asarray(initial.mean, dtype=float)
            cov = np.asarray(initial.cov, dtype=float)
            # Never narrower than a cell: a sharper Gaussian would fall between centres.
            cov = 0.5 * (cov + cov.T) + np.diag([self.cell**2 / 12] * 2 + [self.bin**2 / 12])
            info = np.linalg.inv(cov)
            ex = self.xc[None, :, None] - mean[0]
            ey = self.yc[None, None, :] - mean[1]
            et = wrap(self.theta - mean[2])[:, None, None]
            q = (info[0, 0] * ex * ex + info[1, 1] * ey * ey + info[2, 2] * et * et
                 + 2 * info[0, 1] * ex * ey + 2 * info[0, 2] * ex * et + 2 * info[1, 2] * ey * et)
            self.grid[:] = np.exp(-0.5 * (q - q.min()))
            self.grid /= self.grid.sum()
        self._cache = None
        self._rows = None

    # ----------------------------------------------------------------- motion
    def predict(self, control: Control, dt: float) -> None:
        """Shift each heading slab along its heading, turn, and blur with the motion noise."""
        noise = self.ctx.motion_noise
        # Turning: the whole grid turns by omega dt; whole bins by rolling the heading axis.
        self.phi += control.omega * dt
        k = round(self.phi / self.bin)
        if k:
            self.grid, self._T = _roll_into(self.grid, k, self._T), self.grid
            self.offset = np.roll(self.offset, k, axis=0)
            if self._rows is not None:
                self._rows = np.roll(self._rows, k, axis=0)
            self.phi -= k * self.bin
        d = control.v * dt
        if d != 0.0:   # offsets stay within half a cell: without motion no slab moves
            if self._dir_phi != self.phi:        # the slabs' directions, while phi holds
                th = self.base_th + self.phi
                self._dir = (np.cos(th), np.sin(th))
                self._dir_phi = self.phi
            self.offset[:, 0] += d * self._dir[0]
            self.offset[:, 1] += d * self._dir[1]
            q = self.offset / self.cell
            a = np.abs(q)
            if float(a.max()) > 0.5:   # rint(q) != 0 exactly where |q| > 0.5 (halves to even)
                moving = np.flatnonzero(np.max(a, axis=1) > 0.5)
                shift = np.rint(q).astype(np.int64)
                self.offset[moving] -= shift[moving] * self.cell
                rows = self._rows
                # slab by slab in place (a few slabs a tick): no gathered copies of the grid
                for h, (sx, sy) in zip(moving.tolist(), shift[moving].tolist(), strict=True):
                    slab = self.grid[h]
                    _shift_pile_inplace(slab, sx, sy)
                    if rows is not None:
                        np.matmul(slab, self._yw, out=rows[h])
        # Motion noise, as a variance to blur with.
        sv, sw = noise.control_std(control.v, control.omega)
        ps = noise.pose_std_at(control.v, control.omega)  # slip scales with the command
        self.var_xy += (sv * dt) ** 2 + 0.5 * (ps[0] ** 2 + ps[1] ** 2)
        self.var_th += (sw * dt) ** 2 + ps[2] ** 2
        # Discretisation noise. A slab moves exactly along its bin's centre heading, up to half
        # a bin (5 deg) off the truth, and the update cannot hold the belief between two bins:
        # without this the whole mass collapses into one bin and drifts sideways out of the
        # true cell (seen on `default`: 3 m off after 10 m of driving). While the robot moves
        # or turns, spread a cell's and a bin's uniform variance per `grid_noise` seconds.
        tau = self.params["grid_noise"]
        if tau > 0 and (control.v != 0.0 or control.omega != 0.0):
            self.var_xy += self.cell**2 / 12.0 * dt / tau
            self.var_th += self.bin**2 / 12.0 * dt / tau
        thr = self.params["blur_min"]
        if self.var_xy >= thr * self.cell**2:
            self._blur_xy(self.var_xy / self.cell**2)
            self.var_xy = 0.0
            self._rows = None
        if self.var_th >= thr * self.bin**2:
            self._blur_th(self.var_th / self.bin**2)
            self.var_th = 0.0
            self._rows = None
        self._cache = None

    def _blur_xy(self, var_cells: float) -> None:
        """3-tap blur ``[a, 1 - 2a, a]`` (variance 2a cells^2) along x and y, reflecting at
        the walls; repeated when more variance is due than one pass can hold."""
        g, t = self.grid, self._T
        while var_cells > 1e-12:
            a = min(var_cells / 2.0, 1.0 / 3.0)
            var_cells -= 2.0 * a
            for axis in (1, 2):
                if g.shape[axis] < 2:
                    continue
                # t = previous + next neighbour (the wall cell is its own neighbour), in one
                # pass: the same sums as copying one neighbour and adding the other
                if axis == 1:
                    np.add(g[:, :-2], g[:, 2:], out=t[:, 1:-1])
                    np.add(g[:, 0], g[:, 1], out=t[:, 0])
                    np.add(g[:, -2], g[:, -1], out=t[:, -1])
                else:
                    # along the flattened grid (one contiguous pass; rows of ny - 2 are slow),
                    # then the wall cells of every row, which that pass mixed across rows
                    gf, tf = g.reshape(-1), t.reshape(-1)
                    np.add(gf[:-2], gf[2:], out=tf[1:-1])
                    np.add(g[..., 0], g[..., 1], out=t[..., 0])
                    np.add(g[..., -2], g[..., -1], out=t[..., -1])
                g *= 1.0 - 2.0 * a
                t *= a
                g += t

    def _blur_th(self, var_bins: float) -> None:
        """Circular 3-tap blur along heading."""
        g, nb = self.grid, self._T
        while var_bins > 1e-12:
            a = min(var_bins / 2.0, 1.0 / 3.0)
            var_bins -= 2.0 * a
            np.add(g[:-2], g[2:], out=nb[1:-1])   # the previous bin + the next, circularly
            np.add(g[-1], g[1], out=nb[0])
            np.add(g[-2], g[0], out=nb[-1])
            g *= 1.0 - 2.0 * a
            nb *= a
            g += nb

    # ----------------------------------------------------------------- measurements
    def update(self, measurements: Sequence[Measurement]) -> None:
        """Multiply by the likelihood of this tick's readings over the whole grid."""
        measurements = [m for m in measurements if len(m)]
        if not measurements:
            return
        A = self._A
        C = A[0].reshape(self.nx, self.ny)   # coefficient of cos(theta)
        S = A[1].reshape(self.nx, self.ny)   # coefficient of sin(theta)
        lxy = A[2].reshape(self.nx, self.ny)  # log-likelihood terms in x, y only
        cell_var = self.cell**2 / 6.0         # within-cell position + slab offset
        _, sin_th1, cos_th1 = self._trig()
        cos_th, sin_th = cos_th1[:, None, None], sin_th1[:, None, None]
        # Readings without IDs: a mixture over the beacons, added as ``mixed``.
        measurements, mixed = association.grid_mixture(self, measurements, cos_th, sin_th)
        # Beacon readings without outliers: every reading's C, S and lxy are combinations of
        # five fixed x-y arrays of its beacon (kappa cos a, kappa sin a, kappa, r, r^2, see
        # _beacon_basis), so all of them together are one (3, 5 k) x (5 k, nx ny) product.
        coef: list[list[float]] = [[], [], []]
        blocks: list[np.ndarray] = []
        rest: list[Measurement] = []
        for m in measurements:
            if m.kind not in ("bearing", "range_bearing"):
                rest.append(m)
                continue
            spec = self.ctx.sensor(m.sensor)
            if spec.outlier_rate > 0:
                rest.append(m)
                continue
            std = spec.reading_std()
            ranged = m.kind == "range_bearing"
            sr2 = float(std[0]) ** 2 + cell_var if ranged else 1.0
            for row, b in zip(np.asarray(m.z, dtype=float).tolist(),
                              self.ctx.world.beacon_index(m.beacon_ids).tolist(), strict=True):
                blocks.append(self._beacon_basis(m.sensor, float(std[-1]), b))
                cz, sz = math.cos(row[-1]), math.sin(row[-1])
                # kappa cos(z - alpha + theta) = kappa [cos(z-a) cos(th) - sin(z-a) sin(th)];
                # -0.5 (r - z_r)^2 / sr2 up to a constant (it cancels in the normalisation)
                zr = row[0] / sr2 if ranged else 0.0
                hr = -0.5 / sr2 if ranged else 0.0
                coef[0] += [cz, sz, 0.0, 0.0, 0.0]
                coef[1] += [-sz, cz, 0.0, 0.0, 0.0]
                coef[2] += [0.0, 0.0, -1.0, zr, hr]
        if blocks:
            np.matmul(np.array(coef), np.concatenate(blocks), out=A)
        else:
            A.fill(0.0)
        # ``mixed``: sum of per-reading outlier-mixture (and unlabeled-reading) terms
        for m in rest:
            spec = self.ctx.sensor(m.sensor)
            z = np.asarray(m.z, dtype=float)
            if m.kind in ("bearing", "range_bearing"):      # with an outlier rate
                idx = self.ctx.world.beacon_index(m.beacon_ids)
                std = spec.reading_std()
                eps = spec.outlier_rate
                for row, b in zip(z, idx, strict=True):
                    r = self._r[b]
                    sb2 = std[-1] ** 2 + self.bin**2 / 12 + cell_var / np.maximum(r, self.cell) ** 2
                    kappa = 1.0 / sb2
                    cz, sz = math.cos(row[-1]), math.sin(row[-1])
                    ca, sa = self._ca[b], self._sa[b]
                    cb = kappa * (cz * ca + sz * sa)
                    sbb = -kappa * (sz * ca - cz * sa)
                    lb = -kappa
                    if m.kind == "range_bearing":
                        sr2 = std[0] ** 2 + cell_var
                        lb = lb - 0.5 * (r - row[0]) ** 2 / sr2
                    # Gaussian core mixed with a uniform reading: log((1 - eps) p + eps u),
                    # both relative to the core's peak (the particle filter's form).
                    log_u = -math.log(2 * math.pi) + 0.5 * math.log(2 * math.pi * float(np.min(sb2)))
                    if m.kind == "range_bearing":
                        rmax = spec.max_range if math.isfinite(spec.max_range) else math.hypot(
                            self.ctx.world.width, self.ctx.world.height)
                        log_u += -math.log(rmax) + 0.5 * math.log(2 * math.pi * sr2)
                    core = cos_th * cb[None] + sin_th * sbb[None] + lb[None]
                    term = np.logaddexp(core + math.log1p(-eps), math.log(eps) + log_u)
                    mixed = term if mixed is None else mixed + term
            elif m.kind == "pose":
                std = spec.fix_std(len(m.beacon_ids))
                lxy -= 0.5 * ((self.xc[:, None] - z[0, 0]) ** 2 / (std[0] ** 2 + cell_var)
                              + (self.yc[None, :] - z[0, 1]) ** 2 / (std[1] ** 2 + cell_var))
                kappa = 1.0 / (std[2] ** 2 + self.bin**2 / 12)
                C += kappa * math.cos(z[0, 2])
                S += kappa * math.sin(z[0, 2])
                lxy -= kappa
            elif m.kind == "position":
                h = self._hdop(m.beacon_ids, spec.beacon_height)
                var = (spec.noise.position_std * h) ** 2 + cell_var
                d2 = (self.xc[:, None] - z[0, 0]) ** 2 + (self.yc[None, :] - z[0, 1]) ** 2
                lxy -= 0.5 * d2 / var + np.log(var)      # seed 002 eq. 11, 2-D normalised
            else:   # any other kind: its record's model at every cell and heading
                model = model_of(m.kind)
                if model is None:
                    raise FilterError(f"histogram: unknown measurement kind {m.kind!r}")
                term = model.loglik(spec, m, self._cell_poses(), self.ctx.world).reshape(self.grid.shape)
                mixed = term if mixed is None else mixed + term
        L = self._L
        g = self.grid
        if mixed is None:
            # L = cos(th) C + sin(th) S + lxy as one product (nh, 3) x (3, nx ny). Its peak is
            # taken out with a bound, not a pass over the grid: over all headings
            # C cos + S sin <= hypot(C, S), within (1 - cos(bin / 2)) hypot(C, S) of the grid's
            # peak, and any constant cancels in the normalisation.
            bound = np.hypot(C, S)
            bound += lxy
            peak = float(np.max(bound))
            lxy -= peak
            # Below exp(-600) a cell's likelihood is lost under the floor (eps / cells, times
            # at least e^-600 relative to the peak), so it is clipped there (exp stays off its
            # slow underflow path). x rows whose bound is below that at every y and heading
            # are clipped whole: multiplied by exp(-600) without the product and the exp.
            live = np.flatnonzero(np.max(bound, axis=1) > peak - 600.0 + _CLIP_MARGIN)
            x0, x1 = (int(live[0]), int(live[-1]) + 1) if live.size else (0, 0)
            ny = self.ny
            Lb = L.reshape(-1)[: self.nh * (x1 - x0) * ny].reshape(self.nh, (x1 - x0) * ny)
            trig = np.empty((self.nh, 3))
            trig[:, 0], trig[:, 1], trig[:, 2] = cos_th[:, 0, 0], sin_th[:, 0, 0], 1.0
            np.matmul(trig, A[:, x0 * ny: x1 * ny], out=Lb)
            np.maximum(Lb, -600.0, out=Lb)
            np.exp(Lb, out=Lb)
            g[:, x0:x1] *= Lb.reshape(self.nh, x1 - x0, ny)
            if x0 > 0:
                g[:, :x0] *= _EXP_CLIP
            if x1 < self.nx:
                g[:, x1:] *= _EXP_CLIP
        else:
            np.multiply(cos_th, C[None], out=L)
            L += np.multiply(sin_th, S[None], out=self._T)
            L += lxy[None]
            L += mixed
            L -= L.max()
            np.maximum(L, -600.0, out=L)
            np.exp(L, out=L)
            g *= L
        rows = self._row_sums(g)
        total = float(rows[..., 0].sum())
        eps = self.params["floor"]
        b = eps / g.size
        if not total > 0 or not math.isfinite(total):
            g.fill(1.0 / g.size)   # every cell ruled out (numerically): start over
            self._rows = None
        elif math.isfinite(f := (1.0 - eps) / total):
            g *= f
            g += b
            # the row sums of f g + b: f times those of g, plus b times those of a row of ones
            rows *= f
            rows += b * self._yw_sum
            self._rows = rows
        else:                      # a subnormal total: (1 - eps) / total would overflow
            g /= total
            g *= 1.0 - eps
            g += b
            self._rows = None
        self._cache = None

    def _cell_poses(self) -> np.ndarray:
        """The pose of every cell's centre, (nh nx ny, 3) [m, m, rad], in the grid's order
        [heading, x, y] (for a kind weighed by its record's model)."""
        th = self._trig()[0]
        out = np.empty((self.nh, self.nx, self.ny, 3))
        out[..., 0] = self.xc[None, :, None]
        out[..., 1] = self.yc[None, None, :]
        out[..., 2] = th[:, None, None]
        return out.reshape(-1, 3)

    def _beacon_basis(self, sensor: str, bearing_std: float, b: int) -> np.ndarray:
        """The x-y arrays of beacon ``b`` for a bearing reading of ``sensor``, as rows of a
        (5, nx ny) array: ``kappa cos(alpha)``, ``kappa sin(alpha)``, ``kappa``, ``r``, ``r^2``
        with ``alpha`` the direction and ``r`` the distance from each cell centre to the
        beacon and ``kappa = 1 / (sigma_b^2 + bin^2 / 12 + (cell^2 / 6) / max(r, cell)^2)``
        (the bearing noise inflated by the bin and the cell). Made at a beacon's first
        reading, kept."""
        key = (sensor, bearing_std, b)
        basis = self._basis.get(key)
        if basis is None:
            r = self._r[b].reshape(-1)
            kappa = 1.0 / (bearing_std**2 + self.bin**2 / 12
                           + self.cell**2 / 6.0 / np.maximum(r, self.cell) ** 2)
            basis = np.stack([kappa * self._ca[b].reshape(-1), kappa * self._sa[b].reshape(-1),
                              kappa, r, r * r])
            self._basis[key] = basis
        return basis

    def _hdop(self, ids: np.ndarray, height: float) -> np.ndarray:
        key = (tuple(int(i) for i in np.ravel(ids)), float(height))
        h = self._hdop_cache.get(key)
        if h is None:
            xy = np.stack(np.meshgrid(self.xc, self.yc, indexing="ij"), axis=-1).reshape(-1, 2)
            h = hdop(xy, self.ctx.world.beacon_positions(ids), height).reshape(self.nx, self.ny)
            h = np.minimum(h, 1e3)
            self._hdop_cache[key] = h
        return h

    # ----------------------------------------------------------------- outputs
    def estimate(self) -> tuple[np.ndarray, np.ndarray]:
        """Mean and covariance of the grid (circular heading, wrapped residuals), with the
        within-cell variance ``cell^2 / 12`` and ``bin^2 / 12`` added."""
        if self._cache is None:
            self._cache = self._moments()
        mean, cov = self._cache
        return mean.copy(), cov.copy()

    def _row_sums(self, g: np.ndarray) -> np.ndarray:
        """Per (heading, x) row of ``g`` (k, nx, ny) the sums of p, p y, p y^2: (k, nx, 3)."""
        return (g.reshape(-1, self.ny) @ self._yw).reshape(g.shape[0], self.nx, 3)

    def _moments(self) -> tuple[np.ndarray, np.ndarray]:
        # One pass over the grid (none when the last update or prediction kept them): per
        # (heading, x) row the sums of p, p y and p y^2; then per slab, in one product, the
        # sums of p, p x, p x^2, p y, p x y, p y^2 at the cell centres (unnormalised), and
        # every moment from those (nh, 6) and the slabs' offsets.
        if self._rows is None:
            self._rows = self._row_sums(self.grid)
        M = (self._rows.reshape(self.nh, -1) @ self._xw).T
        p0, sx, sxx, sy, sxy, syy = M
        ox, oy = self.offset[:, 0], self.offset[:, 1]
        Z = np.empty((6, self.nh))
        Z[0] = p0
        np.multiply(ox, p0, out=Z[1])
        Z[1] += sx                              # sum of p x per slab (x with the offset)
        np.multiply(oy, p0, out=Z[2])
        Z[2] += sy                              # p y
        np.add(sx, Z[1], out=Z[3])              # p x^2 = sxx + ox (2 sx + ox p0)
        Z[3] *= ox
        Z[3] += sxx
        np.add(sy, Z[2], out=Z[4])              # p y^2
        Z[4] *= oy
        Z[4] += syy
        np.multiply(oy, Z[1], out=Z[5])         # p x y = sxy + ox sy + oy (sx + ox p0)
        Z[5] += sxy
        Z[5] += ox * sy
        th, sin_th, cos_th = self._trig()
        mth = math.atan2(float(p0 @ sin_th), float(p0 @ cos_th))
        W = np.empty((self.nh, 3))
        W[:, 0] = 1.0
        W[:, 1] = wrap(th - mth)
        np.multiply(W[:, 1], W[:, 1], out=W[:, 2])
        (t0, tx, ty, txx, tyy, txy), (ep, ex, ey, _, _, _), (et2, _, _, _, _, _) = \
            (Z @ W).T.tolist()
        scale = 1.0 / t0
        mx, my = tx * scale, ty * scale
        cov = np.empty((3, 3))
        cov[0, 0] = txx * scale - mx * mx + self.cell**2 / 12
        cov[1, 1] = tyy * scale - my * my + self.cell**2 / 12
        cov[0, 1] = cov[1, 0] = txy * scale - mx * my
        cov[2, 2] = et2 * scale + self.bin**2 / 12
        cov[0, 2] = cov[2, 0] = (ex - mx * ep) * scale
        cov[1, 2] = cov[2, 1] = (ey - my * ep) * scale
        return np.array([mx, my, wrap(mth)]), cov

    def _trig(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The bins' headings (``theta``) with their sines and cosines, kept while ``phi``
        does not change."""
        if self._trig_phi != self.phi:
            th = self.theta
            self._trig_cache = (th, np.sin(th), np.cos(th))
            self._trig_phi = self.phi
        return self._trig_cache

    def belief(self) -> GridBelief:
        """The x-y marginal, shape (nx, ny), for drawing as a heat map."""
        G = self.grid.sum(axis=0)
        return GridBelief(G / G.sum(), self.origin, self.cell)


def _roll_into(g: np.ndarray, k: int, out: np.ndarray) -> np.ndarray:
    """``np.roll(g, k, axis=0)`` written into ``out`` (same shape, not ``g``); returns ``out``."""
    k %= g.shape[0]
    out[k:] = g[: g.shape[0] - k]
    out[:k] = g[g.shape[0] - k:]
    return out


def _shift_pile_inplace(slab: np.ndarray, sx: int, sy: int) -> None:
    """Shift one heading slab ``slab`` (nx, ny) by (sx, sy) cells in place; what would leave
    piles up at the wall, vacated cells become 0."""
    for a, s in ((slab, sx), (slab.T, sy)):    # the shifted axis first
        if s == 0:
            continue
        n = a.shape[0]
        s = max(-(n - 1), min(n - 1, s))
        if s == 0:                             # a single cell along this axis
            continue
        if s > 0:
            pile = a[n - s:].sum(axis=0) if s > 1 else a[n - 1].copy()
            a[s:] = a[: n - s]                 # numpy buffers the overlapping copy
            a[:s] = 0.0
            a[n - 1] += pile
        else:
            pile = a[:-s].sum(axis=0) if s < -1 else a[0].copy()
            a[: n + s] = a[-s:]
            a[n + s:] = 0.0
            a[0] += pile


__all__ = ["TWO_PI", "HistogramFilter"]
