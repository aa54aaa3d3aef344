"""Particle filter (Monte Carlo localization), vectorised: no Python loop over particles.

- Belief: N poses ``[x, y, theta]`` [m, m, rad] with log-weights (long runs never underflow).
- Start: Gaussian around a pose (tracking) or uniform over the world and all headings
  (global localization).
- Motion: each particle executes the command with its own noise drawn from the model's
  ``control_std`` (plus additive ``pose_std``), and is stopped by the walls as the robot is.
- Measurements: bearing, range-bearing, pose fix, and position fix whose standard deviation
  is ``position_std * HDOP`` at each particle (seed 002 eq. 11), optionally times the heading
  term of eq. 14. Bearings use the von Mises form ``exp(kappa (cos(innovation) - 1))``,
  ``kappa = 1 / sigma^2``, which equals the wrapped Gaussian to 4th order in the innovation,
  needs no wrapping and no arctan.
- Resampling when the effective sample size falls below ``ess_threshold * N`` (systematic,
  stratified, residual or multinomial), done at the next update that has measurements, so
  that injected particles are weighted before anyone sees the estimate.
- Recovery: augmented MCL (Thrun et al., Probabilistic Robotics, table 8.3; ROS AMCL's
  ``recovery_alpha_slow/fast``): short- and long-term averages ``w_fast`` / ``w_slow`` of the
  best particle's fit per scalar reading (noise constants left out, so its level does not
  depend on how many beacons a tick saw); at each resampling a share
  ``max(0, 1 - w_fast / w_slow)`` of the particles is replaced by uniform random poses, but
  only while the lost test says recent readings went unexplained (``recovery_fit = "mean"``:
  Thrun's weighted-mean likelihood and no lost gate).
- Lost test: a reading no particle explains at the ``lost_chi2`` point, beyond the declared
  outlier share, raises ``lost``; while it is high the covariance is mixed with a uniform
  pose over the world (``lost_cov``). A weight collapse (ESS < ``COLLAPSE_ESS``) keeps the
  predicted spread / ESS as a floor and jitters the resampled copies by it.
- Adaptive count: KLD-sampling (Fox 2003) between ``n_min`` and ``n_max``, or seed 002's
  scheme (keep drawing until the summed fit of the drawn particles exceeds ``ver_max``).
- Estimate: weighted mean and covariance, circular mean for heading, heading residuals
  wrapped; ``estimate = "cluster"`` summarises the dominant mode only.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.clutter import UNKNOWN_ID
from beacon_sim.core.geometry import hdop
from beacon_sim.core.metrics import chi2_quantile
from beacon_sim.core.motion import MotionNoise
from beacon_sim.core.sensor_kinds import model_of
from beacon_sim.core.types import Control, Measurement
from beacon_sim.filters import association
from beacon_sim.filters.base import FilterBase, FilterContext, FilterError, GaussianBelief, ParticleBelief
from beacon_sim.filters.particle.fast_calls import clip as _clip
from beacon_sim.filters.particle.fast_calls import eigh3 as _eigh
from beacon_sim.filters.particle.fast_calls import reduce_any as _any
from beacon_sim.filters.particle.fast_calls import reduce_max as _max
from beacon_sim.filters.particle.fast_calls import reduce_sum as _sum
from beacon_sim.filters.particle.log_weights import ess as _ess
from beacon_sim.filters.particle.log_weights import logsumexp_inplace as _logsumexp_inplace
from beacon_sim.filters.particle.log_weights import logsumexp_into as _logsumexp_into
from beacon_sim.filters.particle.log_weights import plus as _plus
from beacon_sim.filters.particle.log_weights import scaled_sum as _scaled_sum
from beacon_sim.filters.particle.pose_stats import TWO_PI, weighted_pose_stats
from beacon_sim.filters.resampling import RESAMPLERS, resample

#: Fewer effective particles than this after an update: the weight has collapsed
#: (see ``ParticleFilter._collapse_floor``).
COLLAPSE_ESS = 5.0

#: ``lost`` from which the covariance admits being lost, with no declared outliers: an
#: unexplained reading in the last four ticks with readings at the default ``alpha_fast``.
LOST_AT = 0.1

_MAX_STAGES = 8   # progressive correction: the last stage takes what is left of the likelihood


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


class ParticleFilter(FilterBase):
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
        self._sensor_of: dict[str, Any] = {}   # sensor name -> (spec, constants of _loglik)
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
        (and ``_dims``); returns the position fixes' per-particle normalisation (or None)."""
        n = self.n
        ll = self._fit[:n]
        extra = None
        for m in measurements:  # any position fix: its per-particle normalisation
            if m.kind == "position":
                extra = np.zeros(n)
                break
        dims = 0
        self._tally = [0, 0, 0.0]     # readings, readings no particle explains, expected outliers
        # ll starts at zero: a tick's first bearing reading writes its sum there instead of
        # adding it to zeros (the same bits: 0.0 + x is x, and no log-likelihood is -0.0);
        # any other first reading gets the zeros first
        self._ll_fresh = True
        for m in measurements:
            dims += self._loglik(m, ll, extra)
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
        return extra

    def _progressive_update(self, measurements: Sequence[Measurement], target: float) -> None:
        """Progressive correction (Musso, Oudjane & Le Gland 2001): apply the tick's
        likelihood ``p(z | x)`` as ``p^lambda_1 ... p^lambda_k`` (sum of lambdas 1), each
        stage as large as keeps the effective sample size at ``target`` particles; between
        stages resample and jitter by one kernel bandwidth (``_roughen``), so the particles
        move into the likelihood's peak instead of all but a few being dropped.

        Needed when the likelihood is much sharper than the cloud (a 2 cm pose fix meeting a
        0.5 m cloud after a blind stretch): applied at once it leaves a handful of particles
        whose spread, reported as the covariance, is far smaller than the error.
        Leaves the final stage's log-weights in ``_logw[:n]`` (unnormalised)."""
        n = self.n
        rest = 1.0
        for stage in range(_MAX_STAGES):
            ll = self._fit[:n]
            extra = self._extra
            total = ll if extra is None else ll + extra
            logw = self._logw[:n]
            lam = rest
            buf = self._essbuf[:n]
            if stage < _MAX_STAGES - 1 and _ess(_scaled_sum(logw, rest, total, buf), buf) < target:
                lo, hi = 0.0, rest
                for _ in range(12):                        # ESS falls as lambda grows
                    mid = 0.5 * (lo + hi)
                    ess = _ess(_scaled_sum(logw, mid, total, buf), buf)
                    lo, hi = (mid, hi) if ess >= target else (lo, mid)
                lam = lo
            logw += lam * total
            rest -= lam
            if rest <= 1e-9:
                return
            w = self._wn[:n]
            w[:] = logw
            w -= _logsumexp_inplace(w.copy())
            np.exp(w, out=w)
            w *= 1.0 / w.sum()
            idx = resample(self.params["resampler"], w, n, self.ctx.rng)
            P = self._P2
            for row in range(3):
                np.take(self._P[row, :n], idx, out=P[row, :n])
            self._P, self._P2 = P, self._P
            self._trig_n = 0
            self._logw[:n] = -math.log(n)
            self._roughen(n, 1.0)
            dims = self._dims
            self._extra = self._tick_loglik(measurements)
            self._dims = dims

    def _collapse_floor(self, n: int) -> np.ndarray:
        """The covariance the estimate cannot be below after an update that left fewer than
        ``COLLAPSE_ESS`` effective particles: the predicted cloud's covariance divided by
        the effective sample size, the spread of a weighted mean of that many draws of it.

        Without it a reading far sharper than the cloud (or one that fits a wrong
        particle best, after a kidnap) puts all the weight on one particle; the set then
        reports the spread of one particle's copies (a fraction of a millimetre on
        ``global_kidnap`` while the error was metres) and resampling keeps that. The
        floor is added to the covariance until the next resampling, which jitters the
        copies by it (:meth:`_resample`), so the set keeps the uncertainty it had."""
        _, prior = weighted_pose_stats(self._P[:, :n], self._prior_w[:n])
        return prior / max(self.ess, 1.0)

    def _update_lost(self) -> None:
        """``lost``: the short-term (rate ``alpha_fast``) share of recent readings that no
        particle explains, beyond the share of outliers the sensors declare.

        A reading is unexplained when even the particle that fits it best has a chi-square
        (``-2`` times its Gaussian log-likelihood, constants left out) above the
        ``lost_chi2`` quantile for the reading's degrees of freedom (1 bearing, 2
        range-bearing or position, 3 pose). While tracking, the true pose passes that test
        with probability ``lost_chi2`` and the best particle does at least as well, so
        ``lost`` stays near 0 (near the outlier rate ``eps`` before the correction); after
        a kidnap it climbs by ``alpha_fast`` of what is left on each tick with readings.
        The per-tick share, ``(unexplained / readings - eps) / (1 - eps)``, is averaged;
        ``lost_at`` is ``LOST_AT`` plus three standard deviations of that average when
        every reading is an outlier with probability ``eps`` (one reading a tick: 0.6 at
        eps = 0.2), so that declared outliers alone do not make the filter think it lost."""
        k, bad, eps_sum = self._tally
        if k <= 0:
            return
        eps = min(eps_sum / k, 0.99)
        share = max(0.0, (bad / k - eps) / (1.0 - eps))
        a = self.params["alpha_fast"]
        self.lost += a * (share - self.lost)
        last = self._lost_at_of  # the same (alpha, eps) as last time: the same lost_at
        if last[0] == a and last[1] == eps:
            self.lost_at = last[2]
        else:
            self.lost_at = LOST_AT + 3.0 * math.sqrt(a / max(2.0 - a, 1e-9) * eps / (1.0 - eps))
            self._lost_at_of = (a, eps, self.lost_at)

    def _count_unexplained(self, fits: np.ndarray, dof: int, eps: float) -> None:
        """Tally readings for :meth:`_update_lost`: ``fits`` (k, n) or (n,), the Gaussian
        log-likelihood of each reading at each particle (constants left out, <= 0)."""
        cut = self._chi2_cut.get(dof)
        if cut is None:
            cut = self._chi2_cut[dof] = chi2_quantile(self.params["lost_chi2"], dof)
        best = _max(fits, axis=-1)   # an array (k,), or a numpy scalar for one row
        k = int(best.size)
        self._tally[0] += k
        if k <= 16:   # a few readings: on floats (float32 -> float exactly, the same test)
            vals = best.tolist()
            if type(vals) is list:
                bad = 0
                for b in vals:
                    if -2.0 * b > cut:
                        bad += 1
                self._tally[1] += bad
            else:
                self._tally[1] += int(-2.0 * vals > cut)
        else:
            self._tally[1] += int(np.count_nonzero(-2.0 * np.asarray(best, dtype=np.float64) > cut))
        self._tally[2] += eps * k

    def _update_recovery(self, w_avg: float) -> None:
        """Augmented MCL: ``w_fast`` / ``w_slow`` of the tick's per-reading fit ``w_avg``.

        With ``recovery_fit = "mean"`` (Thrun's form) the fit is the weighted mean
        likelihood. That also falls when the cloud is merely wide (after a blind stretch
        the predicted readings spread over several noise widths): on ``default`` it then
        injected up to 25 % random particles per resampling while tracking, and a single
        range-bearing reading, which fits a whole ring of poses, let those win (seed 5001:
        a 3.6 m excursion, PF 0.965 m against the EKF's 0.122 m). ``"best"`` (default) takes
        the fit of the best particle instead: it stays high while any particle explains
        the readings, and falls only when none does (a kidnap, a wrong mode); and random
        particles are injected only while ``lost`` says a recent tick was unexplained."""
        p = self.params
        if not p["augmented"]:
            self.inject_prob = 0.0
            return
        if self.w_slow == 0.0:
            self.w_slow = self.w_fast = w_avg
        else:
            self.w_slow += p["alpha_slow"] * (w_avg - self.w_slow)
            self.w_fast += p["alpha_fast"] * (w_avg - self.w_fast)
        ratio = self.w_fast / self.w_slow if self.w_slow > 0 else 1.0
        self.inject_prob = min(max(0.0, 1.0 - ratio), p["inject_max"])
        if p["recovery_fit"] == "best" and self.lost < self.lost_at:
            # Thrun's share is positive whenever the short-term average dips below the
            # long-term one, i.e. on half of the ticks by noise alone; random particles
            # injected while tracking fit a one-beacon reading as well as the cloud does
            # (a ring of poses) and pull the estimate off (0.12 m against 0.03 m on
            # global_kidnap). Inject only while recent readings went unexplained.
            self.inject_prob = 0.0

    def _loglik(self, m: Measurement, ll: np.ndarray, extra: np.ndarray | None) -> int:
        """Add the log-likelihood of ``m`` at every particle to ``ll`` (noise constants that
        are the same for all particles left out, so every term is <= 0). Returns the number
        of scalar readings."""
        if self._ll_fresh and m.kind not in ("bearing", "range_bearing"):
            ll[:] = 0.0  # the zeros it adds to (see _tick_loglik)
            self._ll_fresh = False
        if _unlabeled(m):  # unknown correspondence: ML per particle
            if self._ll_fresh:
                ll[:] = 0.0
                self._ll_fresh = False
            return association.particle_loglik(self, m, ll)
        n = self.n
        known = self._sensor_of.get(m.sensor)
        if known is None:
            spec = self.ctx.sensor(m.sensor)
            std = spec.reading_std() if spec.kind in ("bearing", "range_bearing") else None
            known = self._sensor_of[m.sensor] = (spec, std, None if std is None else 1.0 / std[-1] ** 2)
        spec, std, kappa = known
        x, y, th = self._P[0, :n], self._P[1, :n], self._P[2, :n]
        z = np.asarray(m.z, dtype=float)
        eps = spec.outlier_rate
        if m.kind in ("bearing", "range_bearing"):
            if std is None:  # a reading of a kind its sensor does not make
                std = spec.reading_std()
                kappa = 1.0 / std[-1] ** 2
            bx, by = self._beacon_columns(m.beacon_ids)
            k = z.shape[0]
            views = self._views.get((k, n))  # kept per (k, n) (cleared when the work grows)
            T1, T2, T3, DX, DY = views if views is not None else self._scratch(k, n)
            c, s = self._c[:n], self._s[:n]
            if self._trig_n != n:
                np.cos(th, out=c)
                np.sin(th, out=s)
                self._trig_n = n
            cz = np.cos(z[:, -1]).astype(self.dtype)[:, None]
            sz = np.sin(z[:, -1]).astype(self.dtype)[:, None]
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
            if m.kind == "bearing":               # r is not needed after: in place
                np.maximum(T2, 1e-6, out=T2)
                T1 /= T2
            else:
                np.maximum(T2, 1e-6, out=T3)
                T1 /= T3
            T1 -= 1.0
            T1 *= kappa                           # von Mises: kappa (cos(nu) - 1) <= 0
            if m.kind == "range_bearing":
                T2 -= z[:, 0:1].astype(self.dtype)
                T2 *= 1.0 / std[0]
                T2 *= T2
                T2 *= -0.5
                T1 += T2                          # Gaussian range term
            self._count_unexplained(T1, 1 if m.kind == "bearing" else 2, eps)
            if eps > 0:
                # mixture with a uniform reading, log((1 - eps) p + eps u), relative to the peak
                log_u = -math.log(TWO_PI) + 0.5 * math.log(TWO_PI * std[-1] ** 2)
                if m.kind == "range_bearing":
                    rmax = spec.max_range if math.isfinite(spec.max_range) else math.hypot(
                        self.ctx.world.width, self.ctx.world.height)
                    log_u += -math.log(rmax) + 0.5 * math.log(TWO_PI * std[0] ** 2)
                T1[:] = np.logaddexp(T1 + math.log1p(-eps), math.log(eps) + log_u)
            if self._ll_fresh:  # the tick's first reading (see _tick_loglik)
                self._ll_fresh = False
                if k > 1:
                    _sum(T1, axis=0, dtype=np.float64, out=ll)
                else:
                    ll[:] = T1[0]
            else:
                ll += _sum(T1, axis=0, dtype=np.float64) if k > 1 else T1[0]
            return int(z.size)
        if m.kind == "pose":
            std = spec.fix_std(len(m.beacon_ids))
            ex = (x - z[0, 0]) / std[0]
            ey = (y - z[0, 1]) / std[1]
            row = -0.5 * (ex.astype(np.float64) ** 2 + ey ** 2)
            row += (np.cos(th - z[0, 2]) - 1.0) / std[2] ** 2
            self._count_unexplained(row, 3, eps)
            if eps > 0:
                area = self.ctx.world.width * self.ctx.world.height
                log_u = -math.log(area * TWO_PI) + math.log(TWO_PI * std[0] * std[1]) \
                    + 0.5 * math.log(TWO_PI * std[2] ** 2)
                row = np.logaddexp(row + math.log1p(-eps), math.log(eps) + log_u)
            ll += row
            return 3
        if m.kind == "position":
            bxy = self.ctx.world.beacon_positions(m.beacon_ids)
            xy = np.stack([x, y], axis=1)
            h = np.minimum(hdop(xy, bxy, spec.beacon_height), 1e3)
            sd = spec.noise.position_std * h            # seed 002: sigma = HDOP(x_l, y_l) sigma_d
            sd0 = spec.noise.position_std * (m.hdop if math.isfinite(m.hdop) else float(np.min(h)))
            d2 = (x - z[0, 0]).astype(np.float64) ** 2 + (y - z[0, 1]) ** 2
            row = -0.5 * d2 / sd**2
            # 2-D normalisation 1 / (2 pi sd^2), relative to the reported fix's sd0:
            # it differs between particles through HDOP.
            const = -2.0 * np.log(sd / sd0)
            self._count_unexplained(row, 2, eps)
            if eps > 0:
                area = self.ctx.world.width * self.ctx.world.height
                log_u = -math.log(area) + math.log(TWO_PI * sd0**2)
                row = np.logaddexp(row + const + math.log1p(-eps), math.log(eps) + log_u)
                const = 0.0
            ll += row
            if extra is not None:
                extra += const
            return 2
        # Any other kind: its record's model (core/sensor_kinds.py), on the particles as arrays.
        model = model_of(m.kind)
        if model is None:
            raise FilterError(f"pf: unknown measurement kind {m.kind!r}")
        row = model.loglik(spec, m, self._P[:, :n].T.astype(np.float64), self.ctx.world)
        self._count_unexplained(row, int(m.z.size), eps)
        ll += row
        return int(m.z.size)

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
        """How many of the (randomly ordered) candidates to keep."""
        p = self.params
        n_min, n_max = int(p["n_min"]), min(int(p["n_max"]), cand.shape[1])
        if p["adaptive"] == "seed002":
            # Seed 002: stop when the summed likelihood of the drawn particles exceeds Ver_max.
            # Fit per scalar reading (geometric mean), in (0, 1], so Ver_max ~ particles needed
            # when all agree.
            dims = max(self._dims, 1)
            score = np.exp(np.asarray(fit, dtype=np.float64) / dims)
            csum = np.cumsum(score)
            k = int(np.searchsorted(csum, p["ver_max"])) + 1
            return int(np.clip(k, n_min, n_max))
        # KLD-sampling: after j draws occupying k_j bins, stop once j >= n_kld(k_j).
        bxy, bth = p["kld_bin_xy"], p["kld_bin_theta"]
        xmin, ymin, _, _ = self.ctx.world.bounds
        ix = np.floor((cand[0] - xmin) / bxy).astype(np.int64)
        iy = np.floor((cand[1] - ymin) / bxy).astype(np.int64)
        it = np.floor((cand[2] + math.pi) / bth).astype(np.int64)
        key = (ix * 4096 + iy) * 4096 + it
        _, first = np.unique(key, return_index=True)
        is_new = np.zeros(key.shape[0], dtype=np.int64)
        is_new[first] = 1
        bins = np.cumsum(is_new)                  # bins occupied by the first j + 1 draws
        km1 = np.maximum(bins - 1, 1).astype(np.float64)
        a = 2.0 / (9.0 * km1)
        need = km1 / (2.0 * p["kld_epsilon"]) * (1.0 - a + np.sqrt(a) * p["kld_z"]) ** 3
        need[bins <= 1] = 1.0
        j = np.arange(1, key.shape[0] + 1)
        ok = np.flatnonzero((j >= need) & (j >= n_min))
        count = int(ok[0]) + 1 if ok.size else n_max
        return int(np.clip(count, n_min, n_max))

    def _jitter(self, n: int, cov: np.ndarray) -> None:
        """Add Gaussian noise of covariance ``cov`` (3x3) to the first ``n`` particles
        (heading wrapped, positions kept inside the world)."""
        vals, vecs = _eigh(0.5 * (cov + cov.T))
        L = vecs * np.sqrt(np.maximum(vals, 0.0))
        P = self._P[:, :n]
        self._trig_n = 0
        P += (L @ self.ctx.rng.standard_normal((3, n))).astype(self.dtype)
        self._wrap_inplace(P[2])
        xmin, ymin, xmax, ymax = self.ctx.world.bounds
        _clip(P[0], xmin, xmax, out=P[0])
        _clip(P[1], ymin, ymax, out=P[1])

    def _roughen(self, n: int, factor: float | None = None) -> None:
        """Gaussian jitter with ``factor`` (default: the ``roughen`` parameter) times the
        kernel bandwidth (Silverman's rule, 3-D: ``h = n^(-1/7)`` of each dimension's spread)."""
        rng = self.ctx.rng
        P = self._P[:, :n]
        self._trig_n = 0
        h = (self.params["roughen"] if factor is None else factor) * n ** (-1.0 / 7.0)
        sd = np.std(P[:2].astype(np.float64), axis=1)
        th_sd = math.sqrt(max(0.0, -2.0 * math.log(max(
            math.hypot(float(np.mean(np.cos(P[2]))), float(np.mean(np.sin(P[2])))), 1e-12))))
        for row, s in zip(P, (*sd, th_sd), strict=True):
            if s > 0:
                row += (h * s * rng.standard_normal(n)).astype(self.dtype)
        self._wrap_inplace(P[2])

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
                sel = self._dominant_cluster(P, w)
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

    def _with_lost_share(self, mean: np.ndarray, cov: np.ndarray, p_lost: float) -> np.ndarray:
        """Second moment about ``mean`` of the mixture "the cloud with probability
        ``1 - p_lost``, anywhere in the world (uniform pose) with ``p_lost``".

        ``p_lost`` is ``lost`` (:meth:`_update_lost`), used while it is at least
        ``lost_at`` (without outliers: an unexplained reading among the last few ticks):
        the filter's own measure that no particle explains the readings. Without it, after
        a kidnap the weight falls on the one best (still wrong) particle and the reported
        spread is that of its copies (0.4 mm against a 3.85 m error on ``global_kidnap``);
        with it the covariance says the filter may be lost until the readings are
        explained again. While tracking a reading goes unexplained with probability
        ``1 - lost_chi2``; ``lost`` rarely reaches ``lost_at`` then, and only for a few ticks."""
        xmin, ymin, xmax, ymax = self.ctx.world.bounds
        mx, my = mean[0], mean[1]  # float64 scalars, as numpy's entries were
        d0, d1 = 0.5 * (xmin + xmax) - mx, 0.5 * (ymin + ymax) - my
        d0, d1 = float(d0), float(d1)
        c01 = d0 * d1
        # diag + outer(d, d) entry by entry (the same float operations, no small arrays)
        U = np.array([[(xmax - xmin) ** 2 / 12.0 + d0 * d0, 0.0 + c01, 0.0],
                      [0.0 + c01, (ymax - ymin) ** 2 / 12.0 + d1 * d1, 0.0],
                      [0.0, 0.0, math.pi ** 2 / 3.0]])  # uniform heading about any mean
        out = (1.0 - p_lost) * cov + p_lost * U
        return 0.5 * (out + out.T)

    def _dominant_cluster(self, P: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Indices of the particles of the heaviest mode: the coarse x-y cell with the most
        weight in its 3x3 neighbourhood, then all particles within ``cluster_radius`` of that
        neighbourhood's weighted mean."""
        cell = self.params["cluster_cell"]
        xmin, ymin, xmax, ymax = self.ctx.world.bounds
        nx = max(1, math.ceil((xmax - xmin) / cell))
        ny = max(1, math.ceil((ymax - ymin) / cell))
        ix = np.clip(((P[0] - xmin) / cell).astype(np.int64), 0, nx - 1)
        iy = np.clip(((P[1] - ymin) / cell).astype(np.int64), 0, ny - 1)
        H = np.bincount(ix * ny + iy, weights=w, minlength=nx * ny).reshape(nx, ny)
        Hp = np.pad(H, 1)
        S = np.zeros_like(H)
        for a in (-1, 0, 1):
            for b in (-1, 0, 1):
                S += Hp[1 + a: 1 + a + nx, 1 + b: 1 + b + ny]
        cx, cy = np.unravel_index(int(np.argmax(S)), S.shape)
        near = (np.abs(ix - cx) <= 1) & (np.abs(iy - cy) <= 1)
        wn = w[near]
        mx = float(np.dot(wn, P[0][near]) / wn.sum())
        my = float(np.dot(wn, P[1][near]) / wn.sum())
        r = self.params["cluster_radius"]
        sel = np.flatnonzero((P[0] - mx) ** 2 + (P[1] - my) ** 2 <= r * r)
        return sel if sel.size else np.flatnonzero(near)

    def belief(self) -> ParticleBelief:
        """The particles, shape (n, 3) [m, m, rad] (a read-only view, valid until the next
        step), and their normalised weights (n,)."""
        poses = self._P[:, : self.n].T
        poses.flags.writeable = False
        return ParticleBelief(poses, self.weights())

    def _beacon_columns(self, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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

    def _scratch(self, k: int, n: int) -> list[np.ndarray]:
        """Five (k, n) work arrays, reused between calls (the views too, per (k, n))."""
        if self._work is None or self._work.shape[1] < k:
            self._work = np.empty((5, max(k, len(self.ctx.world.beacons)), self.capacity),
                                  dtype=self.dtype)
            self._views.clear()
        views = self._views.get((k, n))
        if views is None:
            if len(self._views) >= 64:
                self._views.clear()
            views = self._views[(k, n)] = [self._work[i, :k, :n] for i in range(5)]
        return views


__all__ = ["COLLAPSE_ESS", "LOST_AT", "TWO_PI", "ParticleFilter", "weighted_pose_stats"]
