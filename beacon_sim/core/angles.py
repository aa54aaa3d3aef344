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
    return wrap_into(arr + np.pi, shifted=True)


def wrap_into(a: np.ndarray, scratch: np.ndarray | None = None, shifted: bool = False) -> np.ndarray:
    """Wrap the float64 array ``a`` [rad] to [-pi, pi) in place and return it: the same bits as
    :func:`wrap`, without its copies (the particle filters' hot paths). ``scratch``: a float64
    array of ``a``'s shape to work in (else one is allocated); ``shifted``: ``a`` already holds
    the angles plus pi."""
    if not shifted:
        a += np.pi
    if a.size < _FAST_WRAP_SIZE or not _shift_into_turn(a, scratch):
        np.mod(a, TWO_PI, out=a)
    a -= np.pi
    # np.mod can round a value just below pi up to exactly pi after the subtraction.
    np.subtract(a, TWO_PI, out=a, where=a >= np.pi)
    return a


#: Arrays at least this long take :func:`_shift_into_turn` (its two reductions cost more than
#: they save on short arrays).
_FAST_WRAP_SIZE = 1024


def _shift_into_turn(x: np.ndarray, scratch: np.ndarray | None = None) -> bool:
    """``np.mod(x, 2 pi)`` in place, bit for bit, by adding or subtracting one turn, when every
    ``x`` lies in (-2 pi, 4 pi) (the difference of two wrapped angles, plus pi: the common case);
    returns False, leaving ``x`` as it was, otherwise (NaN, inf, or further out).

    Why the bits agree: numpy's float remainder is ``fmod``, plus the divisor when the signs
    differ. ``fmod`` is exact, so for x in [2 pi, 4 pi) it is ``x - 2 pi``, which float
    subtraction also gives exactly (Sterbenz); for x in [0, 2 pi) it is x; for x in (-2 pi, 0)
    it is x, and the rounded ``x + 2 pi`` follows, the addition done here too. A -0.0 stays
    -0.0 where numpy gives +0.0, which the caller's ``- pi`` makes the same. ``np.mod`` takes
    about 20 ns an element, this about 5.
    """
    if not (x.min() > -TWO_PI and x.max() < 2.0 * TWO_PI):  # NaN fails both: numpy's path
        return False
    turn = np.empty(x.shape) if scratch is None else scratch
    np.greater_equal(x, TWO_PI, out=turn)  # 1.0 where x is a turn or more, else 0.0
    turn *= TWO_PI
    x -= turn
    np.less(x, 0.0, out=turn)
    turn *= TWO_PI
    x += turn
    return True


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
