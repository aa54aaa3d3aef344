"""95 % bootstrap intervals over runs for the Monte Carlo figures (RMSE/PCRB, ANEES,
recovery time and recovered count).

Runs are the independent unit (the steps of one run are correlated), so each bootstrap
replicate draws ``R`` of the ``R`` runs with replacement and recomputes the figure from the
drawn runs' per-run sums. The generator is seeded with a constant: the same runs give the
same interval, bit for bit. Percentile intervals, the lower end rounded down and the upper
up to drawn values (no interpolation, so "never recovered", an infinite time, stays one).
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np

#: Bootstrap replicates and the generator's seed (a constant: intervals are deterministic).
REPLICATES = 2000
SEED = 26
LEVEL = 0.95


#: Replicates drawn at once: the index array is (BLOCK, R), not (REPLICATES, R), so the
#: memory of an interval grows with the runs 1/20 as fast. The generator gives the same
#: indices drawn in blocks as drawn at once (PCG64 draws them one by one), so the same values.
BLOCK = 100


def _draws(n_runs: int) -> Iterator[np.ndarray]:
    """Run indices of every replicate, int (REPLICATES, n_runs), in blocks of BLOCK rows."""
    rng = np.random.default_rng(SEED)
    for start in range(0, REPLICATES, BLOCK):
        yield rng.integers(0, n_runs, size=(min(BLOCK, REPLICATES - start), n_runs))


def _ends(values: np.ndarray) -> list[float | None] | None:
    """The 95 % percentile interval of ``values`` (replicates,), None if any is NaN."""
    if values.size == 0 or np.isnan(values).any():
        return None
    a = (1.0 - LEVEL) / 2.0
    lo = float(np.percentile(values, 100 * a, method="lower"))
    hi = float(np.percentile(values, 100 * (1 - a), method="higher"))
    return [lo if math.isfinite(lo) else None, hi if math.isfinite(hi) else None]


def ratio_of_sums(num: np.ndarray, den: np.ndarray, sqrt: bool = False) -> list[float | None] | None:
    """Interval of ``sum(num) / sum(den)`` over runs (``num``, ``den``: per-run sums, (R,));
    ``sqrt``: of its square root. None with fewer than two runs."""
    num, den = np.asarray(num, dtype=float), np.asarray(den, dtype=float)
    if num.shape[0] < 2:
        return None
    with np.errstate(invalid="ignore", divide="ignore"):
        v = np.concatenate([num[idx].sum(axis=1) / den[idx].sum(axis=1)
                            for idx in _draws(num.shape[0])])
    return _ends(np.sqrt(v) if sqrt else v)


def median_and_count(times: np.ndarray) -> tuple[list[float | None] | None,
                                                 list[float | None] | None]:
    """Intervals of the median recovery time (a run that never recovered counts as
    infinitely late; an end that is infinite is None, "never") and of the number of runs
    that recovered, from per-run times ``times`` (R,) [s] (inf: never)."""
    t = np.asarray(times, dtype=float)
    if t.shape[0] < 2:
        return None, None
    n = t.shape[0]
    med_blocks, count_blocks = [], []
    for idx in _draws(n):
        drawn = t[idx]
        med = np.sort(drawn, axis=1)[:, (n - 1) // 2: n // 2 + 1]
        with np.errstate(invalid="ignore"):
            med_blocks.append(med.mean(axis=1))   # the median of an even count: the middle two's mean
        count_blocks.append(np.isfinite(drawn).sum(axis=1).astype(float))
    medians = np.concatenate(med_blocks)
    medians[np.isnan(medians)] = math.inf   # inf + inf stays inf; only inf - inf is NaN
    counts = np.concatenate(count_blocks)
    c = _ends(counts)
    return _ends(medians), c


def text(iv: list[float | None] | None, fmt: str) -> str:
    """``"[lo, hi]"`` with ``fmt``; an open end (None) is "never"; no interval: ``""``."""
    if iv is None:
        return ""
    return "[" + ", ".join("never" if v is None else format(v, fmt) for v in iv) + "]"
