"""Angle helpers. Every angle that leaves a function is wrapped to [-pi, pi)."""

from __future__ import annotations

import numpy as np

TWO_PI = 2.0 * np.pi
_PI = float(np.pi)


def wrap(angle):
    """Wrap an angle or array of angles [rad] to [-pi, pi).

    Works on Python floats (returns float) and numpy arrays (returns an array).
    """
    if type(angle) is float or type(angle) is np.float64:
        # Scalars without array overhead: Python's float % is the same IEEE remainder as
        # np.mod (fmod, then + divisor when the signs differ), so the bits are identical.
        a = (float(angle) + _PI) % TWO_PI - _PI
        return a - TWO_PI if a >= _PI else a
    arr = np.asarray(angle, dtype=float)
    if arr.ndim == 0:
        return wrap(float(arr))
    wrapped = np.mod(arr + np.pi, TWO_PI)
    wrapped -= np.pi
    # np.mod can round a value just below pi up to exactly pi after the subtraction.
    np.subtract(wrapped, TWO_PI, out=wrapped, where=wrapped >= np.pi)
    return wrapped


def diff(a, b):
    """Wrapped difference ``a - b`` of angles [rad], in [-pi, pi)."""
    return wrap(np.asarray(a, dtype=float) - np.asarray(b, dtype=float))


def circular_mean(angles, weights=None, axis=None):
    """Weighted circular mean of angles [rad]: ``atan2(sum w sin, sum w cos)``, wrapped.

    Parameters
    ----------
    angles : array_like [rad]
    weights : array_like, optional
        Non-negative weights broadcastable to ``angles``; need not sum to one.
    """
    angles = np.asarray(angles, dtype=float)
    w = np.ones_like(angles) if weights is None else np.asarray(weights, dtype=float)
    s = np.sum(w * np.sin(angles), axis=axis)
    c = np.sum(w * np.cos(angles), axis=axis)
    return wrap(np.arctan2(s, c))
