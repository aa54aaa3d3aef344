"""Regularising the particle filter's set (``filters/particle/pf.py``), after Musso, Oudjane
and Le Gland (2001), "Improving regularised particle filters":

- kernel jitter after resampling (:meth:`Regularisation._roughen`, ``roughen``: Gaussian
  noise of a share of the kernel bandwidth), and by the collapse floor's covariance after a
  weight collapse (:meth:`Regularisation._jitter`);
- progressive correction (:meth:`Regularisation._progressive_update`, ``temper_ess``): a
  likelihood much sharper than the cloud applied in stages, resampling and jittering
  between them, so that the particles move into its peak instead of all but a few being
  dropped.

:class:`Regularisation` is a mixin of :class:`~beacon_sim.filters.particle.pf.ParticleFilter`:
the particles and weights it works on are the filter's.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from beacon_sim.core.types import Measurement
from beacon_sim.filters.base import FilterContext
from beacon_sim.filters.particle.fast_calls import clip as _clip
from beacon_sim.filters.particle.fast_calls import eigh3 as _eigh
from beacon_sim.filters.particle.log_weights import ess as _ess
from beacon_sim.filters.particle.log_weights import logsumexp_inplace as _logsumexp_inplace
from beacon_sim.filters.particle.log_weights import scaled_sum as _scaled_sum
from beacon_sim.filters.resampling import resample

_MAX_STAGES = 8   # progressive correction: the last stage takes what is left of the likelihood


class Regularisation:
    """Kernel jitter and progressive correction, as methods of the particle filter (a
    mixin: the attributes below are the filter's)."""

    ctx: FilterContext
    params: dict[str, Any]
    n: int
    dtype: np.dtype
    _P: np.ndarray
    _P2: np.ndarray
    _logw: np.ndarray
    _wn: np.ndarray
    _fit: np.ndarray
    _essbuf: np.ndarray
    _extra: np.ndarray | None
    _dims: int
    _trig_n: int

    if TYPE_CHECKING:  # the filter's own
        def _tick_loglik(self, measurements: Sequence[Measurement]) -> np.ndarray | None: ...

        def _wrap_inplace(self, a: np.ndarray) -> None: ...

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


__all__ = ["Regularisation"]
