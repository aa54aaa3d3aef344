"""Particle filter (Monte Carlo localization), vectorised: no Python loop over particles.

- Belief: N poses ``[x, y, theta]`` [m, m, rad] with log-weights (long runs never underflow).
- Start: Gaussian around a pose (tracking) or uniform over the world and all headings
  (global localization).
- Motion: each particle executes the command with its own noise drawn from the model's
  ``control_std`` (plus additive ``pose_std``), and is stopped by the walls as the robot is.
- Measurements: any sensor kind, each weighed by its record's model (``particle_fit``,
  core/particle_likelihood.py: the filter lends it its particles and buffers): bearing and
  range-bearing in the von Mises form ``exp(kappa (cos(innovation) - 1))``, pose fix, and
  position fix whose standard deviation is ``position_std * HDOP`` at each particle (seed
  002 eq. 11); optionally times the heading term of eq. 14. The filter tallies each fit for
  its lost test and mixes in the sensor's declared outlier share.
- Resampling when the effective sample size falls below ``ess_threshold * N`` (systematic,
  stratified, residual or multinomial), done at the next update that has measurements, so
  that injected particles are weighted before anyone sees the estimate; optionally
  roughened, and a likelihood much sharper than the cloud applied in stages (progressive
  correction, ``temper_ess``): regularise.py.
- Recovery and the lost test (recovery.py): augmented MCL's random particles, injected only
  while recent readings went unexplained; the covariance mixed with a uniform pose while
  lost (``lost_cov``); after a weight collapse (ESS < ``COLLAPSE_ESS``) the predicted
  spread / ESS kept as a floor, and the resampled copies jittered by it.
- Adaptive count (adaptive_count.py): KLD-sampling (Fox 2003) between ``n_min`` and
  ``n_max``, or seed 002's scheme (keep drawing until the summed fit of the drawn particles
  exceeds ``ver_max``).
- Estimate (pose_stats.py): weighted mean and covariance, circular mean for heading, heading
  residuals wrapped; ``estimate = "cluster"`` summarises the dominant mode only.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.clutter import UNKNOWN_ID
from beacon_sim.core.motion import MotionNoise
from beacon_sim.core.particle_likelihood import with_outliers
from beacon_sim.core.sensor_kinds import model_of
from beacon_sim.core.types import Control, Measurement
from beacon_sim.filters import association
from beacon_sim.filters.base import FilterBase, FilterContext, FilterError, GaussianBelief, ParticleBelief
from beacon_sim.filters.particle.adaptive_count import kld_count, seed002_count
from beacon_sim.filters.particle.fast_calls import clip as _clip
from beacon_sim.filters.particle.fast_calls import reduce_any as _any
from beacon_sim.filters.particle.fast_calls import reduce_max as _max
from beacon_sim.filters.particle.fast_calls import reduce_sum as _sum
from beacon_sim.filters.particle.log_weights import ess as _ess
from beacon_sim.filters.particle.log_weights import logsumexp_inplace as _logsumexp_inplace
from beacon_sim.filters.particle.log_weights import logsumexp_into as _logsumexp_into
from beacon_sim.filters.particle.log_weights import plus as _plus
from beacon_sim.filters.particle.pose_stats import TWO_PI, dominant_cluster, weighted_pose_stats
from beacon_sim.filters.particle.recovery import COLLAPSE_ESS, LOST_AT, Recovery
from beacon_sim.filters.particle.regularise import Regularisation
from beacon_sim.filters.resampling import RESAMPLERS, resample


def _unlabeled(m: Measurement) -> bool:
    """``association.is_unlabeled(m)`` for the usual reading (1-D integer IDs) on lists, a
    microsecond instead of four; anything else asks it."""
    ids = m.beacon_ids
    if type(ids) is np.ndarray and ids.ndim == 1 and ids.dtype.kind in "iu":
        if m.kind not in association.READING_DIMS or not len(m) > 0:
            return False
        lst = ids.tolist()
        return lst.count(UNKNOWN_ID) == len(lst)
    return association.is_unlabeled(m)


class ParticleFilter(FilterBase, Recovery, Regularisation):
    """Sampling importance resampling with augmented-MCL recovery and optional KLD-sampling.

    Attributes for the HUD: ``n`` (current particle count), ``w_slow``, ``w_fast``,
    ``inject_prob`` (share of random particles at the next resampling), ``ess``.
    """

    supports_global = True
    defaults: ClassVar[dict[str, Any]] = {
        "n_particles": 2000,        # fixed count; initial count for adaptive runs
        "n_min": 300,               # adaptive lower bound
        "n_max": 10000,             # adaptive upper bound (and the count after a global reset)
        "resampler": "systematic",  # systematic | stratified | residual | multinomial
        "ess_threshold": 0.5,       # resample when ESS < ess_threshold * N
        "augmented": True,          # augmented-MCL random-particle injection (recovery)
        "alpha_slow": 0.01,         # long-term likelihood average rate (per update)
        "alpha_fast": 0.2,          # short-term likelihood average rate (per update)
        "inject_max": 0.25,         # cap on the share of random particles per resampling
        "recovery_fit": "best",     # best | mean: the fit w_fast / w_slow average (see update)
        "lost_cov": True,           # covariance admits being lost (see _with_lost_share)
        "lost_chi2": 0.999,         # a reading is unexplained when even the best particle's
                                    # chi-square exceeds this quantile for its dof
        "adaptive": "off",          # off | kld | seed002
        "kld_epsilon": 0.05,        # KLD bound between sample and true posterior
        "kld_z": 2.326,             # upper standard normal quantile (0.99)
        "kld_bin_xy": 0.5,          # KLD histogram bin [m]
        "kld_bin_theta": 0.1745,    # KLD histogram bin [rad] (10 deg)
        "ver_max": 500.0,           # seed 002: stop drawing when summed fit exceeds this
        "roughen": 0.0,             # jitter after resampling, in units of the kernel bandwidth
        "temper_ess": 0.0,          # progressive correction: stage an update that would leave
                                    # ESS below this share of N (0: off)
        "estimate": "mean",         # mean | cluster
        "cluster_cell": 0.5,        # [m] coarse grid for finding the dominant mode
        "cluster_radius": 1.0,      # [m] particles within this of the mode make the cluster
        "heading_weight": False,    # seed 002 eq. 14 heading term
        "heading_k_a": 0.03 * math.pi,  # K_a of eq. 13 [rad/s/m... as in the seed]
        "dtype": "float32",         # particle storage: float32 | float64
        "update_min_d": 0.001,      # [m] weight only after the command moved this far ...
        "update_min_a": 0.001,      # [rad] ... or turned this much since the last update
    }

    def __init__(self, ctx: FilterContext):
        super().__init__(ctx)
        p = self.params
        if p["resampler"] not in RESAMPLERS:
            raise FilterError(f"pf: resampler {p['resampler']!r}: use one of {', '.join(RESAMPLERS)}")
        if p["adaptive"] not in ("off", "kld", "seed002"):
            raise FilterError(f"pf: adaptive {p['adaptive']!r}: use off, kld or seed002")
        if p["recovery_fit"] not in ("best", "mean"):
            raise FilterError(f"pf: recovery_fit {p['recovery_fit']!r}: use best or mean")
        if p["estimate"] not in ("mean", "cluster"):
            raise FilterError(f"pf: estimate {p['estimate']!r}: use mean or cluster")
        if p["dtype"] not in ("float32", "float64"):
            raise FilterError(f"pf: dtype {p['dtype']!r}: use float32 or float64")
        if not 0.0 <= p["temper_ess"] <= 1.0:
            raise FilterError(f"pf: temper_ess {p['temper_ess']!r}: use a share of N in [0, 1]")
        if not (1 <= p["n_min"] <= p["n_max"]) or p["n_particles"] < 1:
            raise FilterError("pf: need 1 <= n_min <= n_max and n_particles >= 1")
        self.dtype = np.dtype(p["dtype"])
        self.adaptive = p["adaptive"] != "off"
        self.capacity = int(max(p["n_particles"], p["n_max"]) if self.adaptive else p["n_particles"])
        cap = self.capacity
        # Particles as rows of a (3, cap) array: x, y, theta each contiguous (fast SIMD loops).
        self._P = np.zeros((3, cap), dtype=self.dtype)
        self._P2 = np.zeros((3, cap), dtype=self.dtype)  # resampling target, swapped in
        self._logw = np.zeros(cap)
        self._wn = np.zeros(cap)             # normalised weights (kept in step with _logw)
        self._fit = np.zeros(cap)            # log-likelihood of the last update, per particle
        self._essbuf = np.empty(cap)         # float64 scratch of the ESS tests
        self._prior_w = np.empty(cap)        # the weights before this update
        self._b1 = np.empty(cap, dtype=self.dtype)
        self._b2 = np.empty(cap, dtype=self.dtype)
        self._c = np.empty(cap, dtype=self.dtype)
        self._s = np.empty(cap, dtype=self.dtype)
        self._w32 = np.empty(cap, dtype=self.dtype)
        self._hit = np.empty(cap, dtype=bool)
        self._trig_n = 0   # > 0: _c[:n], _s[:n] are cos, sin of the n particles' headings now
        self._sensor_of: dict[str, Any] = {}   # sensor name -> (spec, kind, model, its constants)
        self._beacons_of: dict[bytes, tuple[np.ndarray, np.ndarray, np.dtype]] = {}  # IDs -> x, y
        self.n = 0
        self.w_slow = 0.0
        self.w_fast = 0.0
        self.inject_prob = 0.0
        self.lost = 0.0
        self.lost_at = LOST_AT
        self._tally: list[float] = [0, 0, 0.0]
        self._ll_fresh = False  # _fit[:n] not yet written this tick (see _tick_loglik)
        self._still_noise: Any = None  # the motion noise known to declare no pose noise
        self._row0: np.ndarray | None = None  # _work[:, 0, :]
        self._lost_at_of: tuple[float, float, float] = (math.nan, math.nan, LOST_AT)  # alpha, eps, lost_at
        self._spread_floor: np.ndarray | None = None
        self._chi2_cut: dict[int, float] = {}
        self.ess = 0.0
        self._pending_resample = False
        self._cache: tuple[np.ndarray, np.ndarray] | None = None
        self._theta_pred = 0.0
        self._last_v = 0.0
        self._dims = 1
        self._work: np.ndarray | None = None
        self._views: dict[tuple[int, int], list[np.ndarray]] = {}  # (k, n) -> _scratch's views
        self._extra: np.ndarray | None = None
        self.reset(None)

    # ----------------------------------------------------------------- initial belief
    def reset(self, initial: GaussianBelief | None) -> None:
        """Gaussian ``initial`` (tracking) or None: uniform over the bounds and all headings."""
        p = self.params
        rng = self.ctx.rng
        if initial is None:
            n = self.capacity if self.adaptive else int(p["n_particles"])
            xmin, ymin, xmax, ymax = self.ctx.world.bounds
            self._P[0, :n] = rng.uniform(xmin, xmax, n)
            self._P[1, :n] = rng.uniform(ymin, ymax, n)
            self._P[2, :n] = rng.uniform(-math.pi, math.pi, n)
        else:
            n = int(np.clip(p["n_particles"], p["n_min"], p["n_max"])) if self.adaptive \
                else int(p["n_particles"])
            mean = np.asarray(initial.mean, dtype=float)
            cov = np.asarray(initial.cov, dtype=float)
            L = np.linalg.cholesky(0.5 * (cov + cov.T) + 1e-12 * np.eye(3))
            draws = mean[:, None] + L @ rng.standard_normal((3, n))
            draws[2] = wrap(draws[2])
            self._P[:, :n] = draws
        self.n = n
        self._logw[:n] = -math.log(n)
        self._wn[:n] = 1.0 / n
        self._fit[:n] = 0.0
        self.w_slow = self.w_fast = 0.0
        self.inject_prob = 0.0
        self.lost = 0.0
        self._spread_floor = None
        self.ess = float(n)
        self._pending_resample = False
        self._cache = None
        self._trig_n = 0
        self._last_v = 0.0
        self._theta_pred = float(self.estimate()[0][2])
        self._moved = (0.0, 0.0)  # command's distance [m] and turn [rad] since the last update
        self._updated = False     # an update since the reset (the first always runs)

    def set_particles(self, poses, weights=None) -> None:
        """Replace the particle set: ``poses`` (n, 3) [m, m, rad], optional weights (n,)."""
        poses = np.asarray(poses, dtype=float).reshape(-1, 3)
        n = poses.shape[0]
        if n > self.capacity:
            raise FilterError(f"pf: {n} particles exceed the capacity {self.capacity}")
        w = np.full(n, 1.0 / n) if weights is None else np.asarray(weights, dtype=float)
        w = w / w.sum()
        self._P[:, :n] = poses.T
        self._P[2, :n] = wrap(poses[:, 2])
        self.n = n
        with np.errstate(divide="ignore"):
            self._logw[:n] = np.maximum(np.log(w), -700.0)
        self._wn[:n] = w
        self._pending_resample = False
        self._cache = None
        self._trig_n = 0

    # ----------------------------------------------------------------- motion
    def predict(self, control: Control, dt: float) -> None:
        """Move every particle with its own noisy copy of the command (walls stop it)."""
        n = self.n
        self._trig_n = 0
        rng = self.ctx.rng
        noise = self.ctx.motion_noise
        x, y, th = self._P[0, :n], self._P[1, :n], self._P[2, :n]
        sv, sw = noise.control_std(control.v, control.omega)
        v = self._b1[:n]
        w = self._b2[:n]
        rng.standard_normal(n, dtype=self.dtype, out=v)
        rng.standard_normal(n, dtype=self.dtype, out=w)
        v *= sv * dt
        v += control.v * dt                       # distance travelled [m]
        w *= sw * dt
        w += control.omega * dt                   # heading change [rad]
        c, s = self._c[:n], self._s[:n]
        np.cos(th, out=c)
        np.sin(th, out=s)
        c *= v
        s *= v
        x += c
        y += s
        th += w
        # slip scales the additive pose noise with the command; none declared: nothing to add
        if noise is not self._still_noise:  # (a frozen MotionNoise declaring no pose noise: none)
            pose_std = getattr(noise, "pose_std", None)
            if pose_std is not None and not any(pose_std) and type(noise) is MotionNoise:
                self._still_noise = noise
        ps = () if noise is self._still_noise else noise.pose_std_at(control.v, control.omega)
        if any(ps):
            for row, std in zip((x, y, th), ps, strict=True):
                if std > 0:
                    rng.standard_normal(n, dtype=self.dtype, out=v)
                    v *= std
                    row += v
        self._wrap_inplace(th)
        xmin, ymin, xmax, ymax = self.ctx.world.bounds
        _clip(x, xmin, xmax, out=x)
        _clip(y, ymin, ymax, out=y)
        self._theta_pred += control.omega * dt
        self._last_v = abs(control.v)
        self._cache = None
        # the standstill gate (AMCL's update_min_d / update_min_a, see update)
        md, ma = self._moved
        self._moved = (md + abs(control.v) * dt, ma + abs(control.omega) * dt)

    def _wrap_inplace(self, a: np.ndarray) -> None:
        """Wrap angles in place to [-pi, pi) (values within a few turns)."""
        t = self._w32[: a.shape[0]]
        np.add(a, math.pi, out=t)
        t *= 1.0 / TWO_PI
        np.floor(t, out=t)
        t *= TWO_PI
        a -= t
        # float32 rounding can leave exactly pi (rarely: test the largest first, one call;
        # a NaN, or any angle at pi, takes the full test)
        if not _max(a) < math.pi:
            hit = self._hit[: a.shape[0]]
            np.greater_equal(a, math.pi, out=hit)
            if _any(hit):
                a[hit] = -math.pi

    # ----------------------------------------------------------------- measurements
    def update(self, measurements: Sequence[Measurement]) -> None:
        """Weight the particles by the likelihood of this tick's readings (log domain)."""
        if type(measurements) is list:  # a list of non-empty Measurements: as it is
            for m in measurements:
                if type(m) is not Measurement or not m.z.shape[0]:  # (len(m) is z's rows)
                    measurements = [m for m in measurements if len(m)]
                    break
        else:
            measurements = [m for m in measurements if len(m)]
        if not measurements:
            return
        # A robot at rest: no weighting until the command has moved update_min_d or turned
        # update_min_a since the last update. Particles that do not move cannot diversify,
        # so weighting and resampling them tick after tick on the same spot collapses the
        # cloud onto a few poses (NEES in the thousands after a minute); AMCL's answer.
        md, ma = self._moved
        if self._updated and md < self.params["update_min_d"] and ma < self.params["update_min_a"]:
            return
        self._moved = (0.0, 0.0)
        self._updated = True
        if "_association" in self.__dict__:  # unknown IDs: forget the last per-particle choices
            association.particle_start(self)
        if self._pending_resample:
            self._resample()
        n = self.n
        extra = self._extra = self._tick_loglik(measurements)
        ll = self._fit[:n]
        logw = self._logw[:n]
        # The predicted weights stay as they are for the collapse floor (the two buffers
        # swap: no copy); the other is scratch and ends as the normalised weights.
        self._prior_w, self._wn = self._wn, self._prior_w
        tmp = self._wn[:n]
        # The tick's fit for augmented MCL.
        best = float(_max(ll))
        self._update_lost()
        if self.params["recovery_fit"] == "best":
            # The best particle's fit: near 1 per reading whenever some particle is where
            # the readings say, however wide the cloud (see _update_recovery).
            w_avg = math.exp(best / max(self._dims, 1))
        else:
            np.add(logw, ll, out=tmp)
            log_marg = _logsumexp_inplace(tmp)
            w_avg = math.exp(log_marg / max(self._dims, 1))
        staged = False
        target = self.params["temper_ess"] * n
        if target > 0 and _ess(_plus(logw, ll, extra, self._essbuf[:n]), self._essbuf[:n]) < target:
            self._progressive_update(measurements, target)
            logw, tmp = self._logw[:n], self._wn[:n]
            staged = True
        else:
            logw += ll
            if extra is not None:
                logw += extra
        logw -= _logsumexp_into(logw, tmp)
        np.maximum(logw, -700.0, out=logw)          # no denormals (they are slow)
        np.exp(logw, out=tmp)
        tmp *= 1.0 / _sum(tmp)
        self.ess = 1.0 / float(np.dot(tmp, tmp))
        self._spread_floor = None
        if self.ess < COLLAPSE_ESS and not staged:
            self._spread_floor = self._collapse_floor(n)
        self._update_recovery(w_avg)
        self._pending_resample = (self.ess < self.params["ess_threshold"] * n
                                  or self.inject_prob > 0.0)
        self._cache = None
        if self.params["heading_weight"]:
            self._theta_pred = float(self.estimate()[0][2])

    def _tick_loglik(self, measurements: Sequence[Measurement]) -> np.ndarray | None:
        """Log-likelihood of all of a tick's readings at every particle, into ``_fit[:n]``
        (and ``_dims``); returns the readings' per-particle normalisation (None: no reading
        had one, e.g. no position fix)."""
        n = self.n
        ll = self._fit[:n]
        self._extra = None            # written by _loglik when a reading has one
        dims = 0
        self._tally = [0, 0, 0.0]     # readings, readings no particle explains, expected outliers
        # ll starts at zero: a tick's first bearing reading writes its sum there instead of
        # adding it to zeros (the same bits: 0.0 + x is x, and no log-likelihood is -0.0);
        # any other first reading gets the zeros first
        self._ll_fresh = True
        for m in measurements:
            dims += self._loglik(m, ll)
        if self._ll_fresh:
            ll[:] = 0.0
            self._ll_fresh = False
        if self.params["heading_weight"]:
            # Seed 002 eqs. 12-14: theta_pred from the last estimate and the commanded turn.
            sa = self.params["heading_k_a"] / max(self._last_v, 0.015)
            e = wrap(self._P[2, :n].astype(np.float64) - self._theta_pred)
            ll += -0.5 * (e / sa) ** 2
            dims += 1
        self._dims = dims
        return self._extra

    def _loglik(self, m: Measurement, ll: np.ndarray) -> int:
        """Add the log-likelihood of ``m`` at every particle to ``ll``: its kind's particle
        form (the record's model, ``particle_fit``: core/particle_likelihood.py), noise
        constants that are the same for all particles left out (so every term is <= 0),
        tallied for the lost test and mixed with the sensor's declared outliers; a
        per-particle normalisation goes into ``_extra``. Returns the number of scalar
        readings."""
        if _unlabeled(m):  # unknown correspondence: ML per particle
            if self._ll_fresh:
                ll[:] = 0.0
                self._ll_fresh = False
            return association.particle_loglik(self, m, ll)
        known = self._sensor_of.get(m.sensor)
        if known is None or known[1] != m.kind:
            spec = self.ctx.sensor(m.sensor)
            model = model_of(m.kind)
            if model is None:
                raise FilterError(f"pf: unknown measurement kind {m.kind!r}")
            known = self._sensor_of[m.sensor] = (spec, m.kind, model, model.particle_constants(spec))
        spec, _, model, consts = known
        fit = model.particle_fit(spec, consts, m, self, self.ctx.world)
        fits, dof, scalars, log_u, const = fit
        eps = spec.outlier_rate
        self._count_unexplained(fits, dof, eps)
        if eps > 0 and log_u is not None:
            fits, const = with_outliers(fit, eps)
        if fits.ndim == 2:  # one row per beacon: their sum
            k = fits.shape[0]
            if self._ll_fresh:  # the tick's first reading (see _tick_loglik)
                self._ll_fresh = False
                if k > 1:
                    _sum(fits, axis=0, dtype=np.float64, out=ll)
                else:
                    ll[:] = fits[0]
            else:
                ll += _sum(fits, axis=0, dtype=np.float64) if k > 1 else fits[0]
        else:
            if self._ll_fresh:
                ll[:] = 0.0
                self._ll_fresh = False
            ll += fits
        if const is not None:
            if self._extra is None:
                self._extra = np.zeros(self.n)
            self._extra += const
        return scalars

    # ----------------------------------------------------------------- resampling
    def _resample(self) -> None:
        """Draw a new, equally weighted set (count by the adaptive scheme), inject random
        particles at the augmented-MCL rate, roughen if asked."""
        p = self.params
        rng = self.ctx.rng
        n_old = self.n
        self._trig_n = 0
        w = self._wn[:n_old]
        if not self.adaptive:
            n_new = n_old
            idx = resample(p["resampler"], w, n_new, rng)
        else:
            n_cand = self.capacity
            idx = resample(p["resampler"], w, n_cand, rng)
            idx = idx[rng.permutation(n_cand)]  # a prefix must be a fair sample
        P = self._P2
        m = int(idx.shape[0])
        self._P[0, :n_old].take(idx, out=P[0, :m])  # np.take without its Python layer
        self._P[1, :n_old].take(idx, out=P[1, :m])
        self._P[2, :n_old].take(idx, out=P[2, :m])
        fit = self._fit[:n_old][idx] if p["adaptive"] == "seed002" else None
        if self.inject_prob > 0:
            mask = rng.random(m) < self.inject_prob
            k = int(mask.sum())
            if k:
                xmin, ymin, xmax, ymax = self.ctx.world.bounds
                P[0, :m][mask] = rng.uniform(xmin, xmax, k)
                P[1, :m][mask] = rng.uniform(ymin, ymax, k)
                P[2, :m][mask] = rng.uniform(-math.pi, math.pi, k)
                if fit is not None:
                    fit[mask] = -np.inf
        if self.adaptive:
            m = self._adaptive_count(P[:, :m], fit)
        self._P, self._P2 = P, self._P
        self.n = m
        self._logw[:m] = -math.log(m)
        self._wn[:m] = 1.0 / m
        if self._spread_floor is not None:
            self._jitter(m, self._spread_floor)
            self._spread_floor = None
        elif p["roughen"] > 0:
            self._roughen(m)
        self._pending_resample = False
        self._cache = None

    def _adaptive_count(self, cand: np.ndarray, fit: np.ndarray | None) -> int:
        """How many of the (randomly ordered) candidates to keep (adaptive_count.py)."""
        p = self.params
        n_min, n_max = int(p["n_min"]), min(int(p["n_max"]), cand.shape[1])
        if p["adaptive"] == "seed002":
            return seed002_count(fit, self._dims, p["ver_max"], n_min, n_max)
        return kld_count(cand, self.ctx.world.bounds, p["kld_bin_xy"], p["kld_bin_theta"],
                         p["kld_epsilon"], p["kld_z"], n_min, n_max)

    # ----------------------------------------------------------------- outputs
    def weights(self) -> np.ndarray:
        """Normalised weights, shape (n,) (a copy)."""
        return self._wn[: self.n].copy()

    def estimate(self) -> tuple[np.ndarray, np.ndarray]:
        """Weighted mean and covariance ([m, m, rad]; heading circular, residuals wrapped)."""
        if self._cache is None:
            n = self.n
            w = self._wn[:n]
            P = self._P[:, :n]
            trig = (self._s[:n], self._c[:n]) if self._trig_n == n else None
            if self.params["estimate"] == "cluster":
                sel = dominant_cluster(P, w, self.ctx.world.bounds, self.params["cluster_cell"],
                                       self.params["cluster_radius"])
                P, w, trig = P[:, sel], w[sel] / w[sel].sum(), None
            if self._work is None or self._work.shape[1] < 4:
                self._work = np.empty((5, max(4, len(self.ctx.world.beacons)), self.capacity),
                                      dtype=self.dtype)
                self._views.clear()
            row0 = self._row0  # the estimate's scratch view, kept while the work is the same
            if row0 is None or row0.base is not self._work:
                row0 = self._row0 = self._work[:, 0, :]
            mean, cov = weighted_pose_stats(P, w, row0, trig)
            if self._spread_floor is not None:
                cov = cov + self._spread_floor
            if self.params["lost_cov"] and self.lost >= self.lost_at:
                cov = self._with_lost_share(mean, cov, self.lost)
            self._cache = (mean, cov)
        mean, cov = self._cache
        return mean.copy(), cov.copy()

    def belief(self) -> ParticleBelief:
        """The particles, shape (n, 3) [m, m, rad] (a read-only view, valid until the next
        step), and their normalised weights (n,)."""
        poses = self._P[:, : self.n].T
        poses.flags.writeable = False
        return ParticleBelief(poses, self.weights())

    # ------------------------------------------- the particles lent to a kind's particle_fit
    # (core/particle_likelihood.py's ParticleCloud: the filter's buffers, nothing allocated)
    def xy_theta(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The particles' x [m], y [m] and theta [rad], each (n,) (views)."""
        P, n = self._P, self.n
        return P[0, :n], P[1, :n], P[2, :n]

    def trig(self) -> tuple[np.ndarray, np.ndarray]:
        """cos and sin of the particles' headings, each (n,), worked out once per motion."""
        n = self.n
        c, s = self._c[:n], self._s[:n]
        if self._trig_n != n:
            np.cos(self._P[2, :n], out=c)
            np.sin(self._P[2, :n], out=s)
            self._trig_n = n
        return c, s

    def poses64(self) -> np.ndarray:
        """The particles as float64 poses (n, 3) (a copy)."""
        return self._P[:, :self.n].T.astype(np.float64)

    def beacon_columns(self, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The x and y [m] of these beacons as columns (k, 1) of the particles' dtype,
        remembered per set of IDs (an unknown ID raises as ``World.beacon_positions``)."""
        key = ids.tobytes()
        cols = self._beacons_of.get(key)
        if cols is None or cols[2] != ids.dtype:
            bxy = self.ctx.world.beacon_positions(ids)
            cols = (bxy[:, 0:1].astype(self.dtype), bxy[:, 1:2].astype(self.dtype), ids.dtype)
            if len(self._beacons_of) >= 4096:
                self._beacons_of.clear()
            self._beacons_of[key] = cols
        return cols[0], cols[1]

    def scratch(self, k: int) -> list[np.ndarray]:
        """Five (k, n) work arrays, reused between calls (the views too, per (k, n))."""
        n = self.n
        views = self._views.get((k, n))  # kept per (k, n) (cleared when the work grows)
        if views is not None:
            return views
        if self._work is None or self._work.shape[1] < k:
            self._work = np.empty((5, max(k, len(self.ctx.world.beacons)), self.capacity),
                                  dtype=self.dtype)
            self._views.clear()
        if len(self._views) >= 64:
            self._views.clear()
        views = self._views[(k, n)] = [self._work[i, :k, :n] for i in range(5)]
        return views


__all__ = ["COLLAPSE_ESS", "LOST_AT", "TWO_PI", "ParticleFilter", "weighted_pose_stats"]
