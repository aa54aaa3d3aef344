"""Arithmetic on a particle set's log-weights (unnormalised, float64, shape (n,)): the
effective sample size, log-sum-exp, sums into scratch arrays, with no allocation on the
particle filter's update path."""

from __future__ import annotations

import math

import numpy as np

from beacon_sim.filters.particle.fast_calls import reduce_max as _max
from beacon_sim.filters.particle.fast_calls import reduce_sum as _sum


def ess(logw: np.ndarray, out: np.ndarray | None = None) -> float:
    """Effective sample size ``(sum w)^2 / sum w^2`` of unnormalised log-weights (n,);
    ``out`` (n,) float64 scratch (may be ``logw`` itself) saves the allocations."""
    w = np.subtract(logw, float(_max(logw)), out=out)
    np.exp(w, out=w)
    return float(_sum(w) ** 2 / np.dot(w, w))


def scaled_sum(logw: np.ndarray, lam: float, total: np.ndarray, out: np.ndarray) -> np.ndarray:
    """``logw + lam * total`` into ``out`` (the same operations, no allocation)."""
    np.multiply(total, lam, out=out)
    out += logw
    return out


def plus(logw: np.ndarray, ll: np.ndarray, extra: np.ndarray | None, out: np.ndarray) -> np.ndarray:
    """``logw + ll (+ extra)`` into ``out``."""
    np.add(logw, ll, out=out)
    if extra is not None:
        out += extra
    return out


def logsumexp_into(a: np.ndarray, out: np.ndarray) -> float:
    """log(sum(exp(a))), with ``out`` (like ``a``) as scratch: :func:`logsumexp_inplace` of a
    copy of ``a``, without the copy (the same operations on the same values)."""
    m = float(_max(a))
    if not math.isfinite(m):
        return m
    np.subtract(a, m, out=out)
    np.maximum(out, -700.0, out=out)
    np.exp(out, out=out)
    return m + math.log(float(_sum(out)))


def logsumexp_inplace(a: np.ndarray) -> float:
    """log(sum(exp(a))), using ``a`` as scratch (it is overwritten)."""
    m = float(_max(a))
    if not math.isfinite(m):
        return m
    a -= m
    np.maximum(a, -700.0, out=a)   # exp of values below -745 underflows on a 10x slower path
    np.exp(a, out=a)
    return m + math.log(float(_sum(a)))


__all__ = ["ess", "logsumexp_inplace", "logsumexp_into", "plus", "scaled_sum"]
