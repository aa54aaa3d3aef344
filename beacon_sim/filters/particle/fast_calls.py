"""numpy calls without their Python layers, for the particle filters' hot loops: the same
results as ``np.clip``, ``ndarray.max`` / ``sum`` / ``any`` and ``np.linalg.eigh`` of a 3x3,
a few microseconds a call cheaper (tests/filters/test_speed_paths.py holds them equal)."""

from __future__ import annotations

import math

import numpy as np


def find_clip():
    """The ufunc ``np.clip`` ends in (its Python layers cost ~3 us a call on small arrays);
    absent: ``np.clip`` itself. The same values either way."""
    core = getattr(np, "_core", None) or getattr(np, "core", None)
    return getattr(getattr(core, "umath", None), "clip", None) or np.clip


clip = find_clip()
# The reductions behind ndarray.max / sum and np.max / np.sum, called directly: the same
# results without their Python layers (1-1.5 us a call, a few per step).
reduce_max = np.maximum.reduce
reduce_min = np.minimum.reduce
reduce_sum = np.add.reduce
reduce_any = np.logical_or.reduce


def find_eigh():
    """The gufunc ``np.linalg.eigh`` calls for a real array (``UPLO="L"``); absent: None."""
    ul = getattr(np.linalg, "_umath_linalg", None)
    return getattr(ul, "eigh_lo", None)


EIGH_LO = find_eigh()


def eigh3(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.linalg.eigh(a)`` of a float64 3x3 ``a``: the same LAPACK call and results without
    its Python layers (~7 us of a ~12 us call). Non-finite entries take ``np.linalg.eigh``
    itself (its LinAlgError); a finite symmetric 3x3 always converges."""
    r0, r1, r2 = a.tolist()
    if EIGH_LO is None or not math.isfinite(sum(r0) + sum(r1) + sum(r2)):
        vals, vecs = np.linalg.eigh(a)
        return vals, vecs
    vals, vecs = EIGH_LO(a, signature="d->dd")
    return vals, vecs



__all__ = ["EIGH_LO", "clip", "eigh3", "find_clip", "find_eigh", "reduce_any", "reduce_max", "reduce_min",
           "reduce_sum"]
