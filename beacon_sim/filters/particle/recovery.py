"""The particle filter's lost test and augmented-MCL recovery (``filters/particle/pf.py``),
and the covariance that admits being lost or collapsed.

- Lost test: a reading no particle explains at the ``lost_chi2`` point, beyond the declared
  outlier share, raises ``lost`` (:meth:`Recovery._update_lost`); while it is high the
  covariance is mixed with a uniform pose over the world (``lost_cov``,
  :meth:`Recovery._with_lost_share`).
- Recovery: augmented MCL (Thrun et al., Probabilistic Robotics, table 8.3; ROS AMCL's
  ``recovery_alpha_slow/fast``): short- and long-term averages ``w_fast`` / ``w_slow`` of the
  best particle's fit per scalar reading (noise constants left out, so its level does not
  depend on how many beacons a tick saw); at each resampling a share
  ``max(0, 1 - w_fast / w_slow)`` of the particles is replaced by uniform random poses, but
  only while the lost test says recent readings went unexplained (``recovery_fit = "mean"``:
  Thrun's weighted-mean likelihood and no lost gate) (:meth:`Recovery._update_recovery`).
- Collapse: an update that leaves fewer than ``COLLAPSE_ESS`` effective particles keeps the
  predicted spread / ESS as a floor (:meth:`Recovery._collapse_floor`).

:class:`Recovery` is a mixin of :class:`~beacon_sim.filters.particle.pf.ParticleFilter`: its
state (``lost``, ``lost_at``, ``w_slow``, ``w_fast``, ``inject_prob``, the tick's tally) is
the filter's, read by the HUD.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from beacon_sim.core.metrics import chi2_quantile
from beacon_sim.filters.base import FilterContext
from beacon_sim.filters.particle.fast_calls import reduce_max as _max
from beacon_sim.filters.particle.pose_stats import weighted_pose_stats

#: Fewer effective particles than this after an update: the weight has collapsed
#: (see ``Recovery._collapse_floor``).
COLLAPSE_ESS = 5.0

#: ``lost`` from which the covariance admits being lost, with no declared outliers: an
#: unexplained reading in the last four ticks with readings at the default ``alpha_fast``.
LOST_AT = 0.1


class Recovery:
    """The lost test, augmented MCL's random share and the honest covariance, as methods of
    the particle filter (a mixin: the attributes below are the filter's)."""

    ctx: FilterContext
    params: dict[str, Any]
    n: int
    ess: float
    lost: float
    lost_at: float
    w_slow: float
    w_fast: float
    inject_prob: float
    _P: np.ndarray
    _prior_w: np.ndarray
    _tally: list[float]
    _chi2_cut: dict[int, float]
    _lost_at_of: tuple[float, float, float]

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


__all__ = ["COLLAPSE_ESS", "LOST_AT", "Recovery"]
