"""Resampling schemes for particle filters: which ancestor each new particle copies.

Every scheme is unbiased: the expected number of copies of particle i is ``n_out * w_i``.
They differ in variance (multinomial > stratified, residual > systematic). All are
vectorised (no Python loop over particles) and draw only from the generator they are given.
"""

from __future__ import annotations

import numpy as np

RESAMPLERS = ("systematic", "stratified", "residual", "multinomial")


def _scaled_cumsum(weights: np.ndarray, n_out: int) -> np.ndarray:
    """``n_out * cumsum(w)`` with the last entry forced to exactly ``n_out`` (rounding)."""
    c = np.add.accumulate(weights, dtype=np.float64)  # np.cumsum without its Python layers
    c *= n_out / c[-1]
    c[-1] = n_out
    return c


def systematic(weights: np.ndarray, n_out: int, rng: np.random.Generator) -> np.ndarray:
    """One uniform offset ``u``; new particle k copies the ancestor whose cumulative-weight
    interval holds ``(u + k) / n_out``. Particle i gets ``floor`` or ``ceil`` of ``n_out w_i``
    copies. Returns sorted ancestor indices, shape (n_out,)."""
    c = _scaled_cumsum(weights, n_out)
    u = rng.random()
    # Number of points u + k (k = 0..n_out-1) below each boundary c_i: ceil(c_i - u).
    c -= u
    np.ceil(c, out=c)
    below = c.astype(np.int64)
    np.maximum(below, 0, out=below)
    np.minimum(below, n_out, out=below)
    counts = np.empty_like(below)              # np.diff(below, prepend=0), without its copies
    counts[0] = below[0]
    np.subtract(below[1:], below[:-1], out=counts[1:])
    return np.repeat(_arange(weights.shape[0]), counts)


_ARANGE = np.arange(0)


def _arange(n: int) -> np.ndarray:
    """``np.arange(n)`` (int64), a read-only view of one kept array (grown as needed)."""
    global _ARANGE
    if _ARANGE.shape[0] < n:
        _ARANGE = np.arange(max(n, 2 * _ARANGE.shape[0]), dtype=np.int64)
        _ARANGE.flags.writeable = False
    return _ARANGE[:n]


def stratified(weights: np.ndarray, n_out: int, rng: np.random.Generator) -> np.ndarray:
    """One independent uniform per stratum ``[k, k + 1) / n_out``. Sorted indices (n_out,)."""
    c = _scaled_cumsum(weights, n_out)
    points = np.arange(n_out, dtype=np.float64) + rng.random(n_out)
    idx = np.searchsorted(c, points, side="right")
    return np.minimum(idx, weights.shape[0] - 1)


def residual(weights: np.ndarray, n_out: int, rng: np.random.Generator) -> np.ndarray:
    """``floor(n_out w_i)`` copies each, the remaining ``R`` by a multinomial draw on the
    residual weights ``(n_out w_i - floor(n_out w_i)) / R``. Sorted indices (n_out,)."""
    w = np.asarray(weights, dtype=np.float64)
    scaled = w * (n_out / w.sum())
    counts = np.floor(scaled).astype(np.int64)
    rest = n_out - int(counts.sum())
    if rest > 0:
        res = scaled - counts
        res = np.clip(res, 0.0, None)
        counts += rng.multinomial(rest, res / res.sum())
    return np.repeat(np.arange(w.shape[0]), counts)


def multinomial(weights: np.ndarray, n_out: int, rng: np.random.Generator) -> np.ndarray:
    """``n_out`` independent draws from the weights. Sorted indices (n_out,)."""
    w = np.asarray(weights, dtype=np.float64)
    counts = rng.multinomial(n_out, w / w.sum())
    return np.repeat(np.arange(w.shape[0]), counts)


def resample(name: str, weights: np.ndarray, n_out: int, rng: np.random.Generator) -> np.ndarray:
    """Ancestor indices, shape (n_out,), by the scheme called ``name`` (see ``RESAMPLERS``)."""
    if name == "systematic":
        return systematic(weights, n_out, rng)
    if name == "stratified":
        return stratified(weights, n_out, rng)
    if name == "residual":
        return residual(weights, n_out, rng)
    if name == "multinomial":
        return multinomial(weights, n_out, rng)
    raise ValueError(f"unknown resampler {name!r}: use one of {', '.join(RESAMPLERS)}")


def effective_sample_size(weights: np.ndarray) -> float:
    """``1 / sum(w^2)`` for normalised weights: N for equal weights, 1 for a single one."""
    w = np.asarray(weights, dtype=np.float64)
    return float(1.0 / np.dot(w, w))
