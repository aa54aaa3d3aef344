"""How many particles to keep after a resampling (``adaptive`` of the particle filter):
KLD-sampling (Fox 2003) or seed 002's scheme, each between ``n_min`` and ``n_max``.

Both take the candidates drawn by the resampler in a random order, so that any prefix is a
fair sample, and return how long a prefix to keep.
"""

from __future__ import annotations

import math

import numpy as np


def seed002_count(fit: np.ndarray | None, dims: int, ver_max: float, n_min: int, n_max: int) -> int:
    """Seed 002: stop when the summed likelihood of the drawn particles exceeds ``ver_max``.
    ``fit`` (m,) is each candidate's log-likelihood of the last update over ``dims`` scalar
    readings; its fit per scalar reading (geometric mean) is in (0, 1], so ``ver_max`` is
    about the particles needed when all agree."""
    dims = max(dims, 1)
    score = np.exp(np.asarray(fit, dtype=np.float64) / dims)
    csum = np.cumsum(score)
    k = int(np.searchsorted(csum, ver_max)) + 1
    return int(np.clip(k, n_min, n_max))


def kld_count(cand: np.ndarray, bounds: tuple[float, float, float, float], bin_xy: float,
              bin_theta: float, epsilon: float, z: float, n_min: int, n_max: int) -> int:
    """KLD-sampling: after j draws occupying k_j bins of ``bin_xy`` [m] by ``bin_theta`` [rad]
    (``cand`` (3, m) rows x, y, theta; ``bounds`` the world's ``(xmin, ymin, xmax, ymax)``),
    stop once ``j >= (k_j - 1) / (2 epsilon) (1 - a + sqrt(a) z)^3``, ``a = 2 / (9 (k_j - 1))``:
    the sample whose KL divergence from the true posterior is below ``epsilon`` with the
    probability of the standard normal quantile ``z``."""
    xmin, ymin, _, _ = bounds
    ix = np.floor((cand[0] - xmin) / bin_xy).astype(np.int64)
    iy = np.floor((cand[1] - ymin) / bin_xy).astype(np.int64)
    it = np.floor((cand[2] + math.pi) / bin_theta).astype(np.int64)
    key = (ix * 4096 + iy) * 4096 + it
    _, first = np.unique(key, return_index=True)
    is_new = np.zeros(key.shape[0], dtype=np.int64)
    is_new[first] = 1
    bins = np.cumsum(is_new)                  # bins occupied by the first j + 1 draws
    km1 = np.maximum(bins - 1, 1).astype(np.float64)
    a = 2.0 / (9.0 * km1)
    need = km1 / (2.0 * epsilon) * (1.0 - a + np.sqrt(a) * z) ** 3
    need[bins <= 1] = 1.0
    j = np.arange(1, key.shape[0] + 1)
    ok = np.flatnonzero((j >= need) & (j >= n_min))
    count = int(ok[0]) + 1 if ok.size else n_max
    return int(np.clip(count, n_min, n_max))


__all__ = ["kld_count", "seed002_count"]
