"""The guard: what every front end (``run``, ``eval``, ``grade``, the window, the isolated
host) uses to judge what a filter returned, so that nothing a filter returns reaches a
metric or the renderer unchecked.

:func:`validate_estimate` judges ``estimate()`` (a ``(mean (3,), cov (3, 3))`` pair [m, m,
rad], world frame); :func:`validate_belief` judges ``belief()``. Both return fresh float
arrays or one line saying why the value is unusable.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable

import numpy as np

from beacon_sim.filters.base import Belief, GaussianBelief, GridBelief, ParticleBelief

_F8 = np.dtype(float)

#: The largest |mean| entry [m or rad] and covariance entry [m^2 or rad^2] an estimate may
#: hold: beyond them the filter has diverged (and the metrics' products would overflow).
MAX_MEAN = 1e9
MAX_COV = 1e12


def _as_numbers(x: object) -> np.ndarray | None:
    """``x`` as a float array, or None when it is not numbers (strings, objects, complex)."""
    if type(x) is np.ndarray and x.dtype == _F8:  # the usual case, fast
        return x.copy()
    try:
        a = np.asarray(x)
    except Exception:  # an object whose __array__ raises
        return None
    if a.dtype.kind not in "biuf":
        return None
    return a.astype(float, copy=True)


def _type_name(x: object) -> str:
    return "None" if x is None else type(x).__name__


#: The guard's semi-definiteness threshold, relative to the largest entry: a covariance is
#: refused when an eigenvalue is below ``-PSD_TOLERANCE * max|entry|``.
PSD_TOLERANCE = 1e-9
#: How far from that threshold the guard's verdict may differ from an eigenvalue test
#: (``numpy.linalg.eigvalsh``), relative to the largest entry: only a matrix whose smallest
#: eigenvalue lies within this of ``-PSD_TOLERANCE * max|entry|`` may be judged either way
#: (tests/hosting/test_guard_eigen.py checks it on near-singular covariances).
PSD_AGREEMENT = 1e-12


def _not_psd(a: float, b: float, d: float, e: float, f: float, g: float) -> bool:
    """Whether the symmetric 3x3 ``[[a, b, d], [b, e, f], [d, f, g]]`` (finite floats) has
    an eigenvalue below ``-PSD_TOLERANCE * max|entry|``: a Cholesky factorisation of the
    matrix plus ``PSD_TOLERANCE max|entry| I`` (a few float operations instead of an
    eigen-decomposition). Cholesky is backward stable, so the verdict is the eigenvalue
    test's within :data:`PSD_AGREEMENT`; the determinants of the leading minors were not (a
    near-singular covariance, eigenvalues 1e-12, 1.3e-12 and 0.027, lost its determinant to
    rounding and was refused)."""
    tol = PSD_TOLERANCE * max(abs(a), abs(b), abs(d), abs(e), abs(f), abs(g), 1e-12)
    a, e, g = a + tol, e + tol, g + tol
    if a <= 0.0:
        return True
    e1 = e - b * (b / a)
    if e1 <= 0.0:
        return True
    f1 = f - d * (b / a)
    return g - d * (d / a) - f1 * (f1 / e1) <= 0.0


def _getrefcount(x: object) -> int:
    return 1 << 30  # no reference counts here (not CPython): always copy


if hasattr(sys, "getrefcount"):
    _getrefcount = sys.getrefcount  # type: ignore[assignment]


def _sole_probe(est: tuple[np.ndarray, np.ndarray]) -> tuple[int, int]:
    m0, _c0 = est  # the locals validate_estimate holds when it counts
    return _getrefcount(est), _getrefcount(m0)


def _sole_refs() -> tuple[int, int]:
    est = (np.zeros(3), np.eye(3))  # held by one local of the caller, as the runner holds it
    return _sole_probe(est)


#: The reference counts of an estimate pair and of each of its arrays when nothing but the
#: caller's one variable holds the pair and nothing but the pair holds the arrays (measured
#: here, once): with ``sole=True``, arrays at these counts are returned as they are, without
#: a copy. Every holder of a Python object counts (a filter's attribute, a list, the tuple
#: kept, a view's ``base``), so no one but the caller can reach, or change, such arrays.
_SOLE_PAIR, _SOLE_ARRAY = _sole_refs()


def validate_estimate(est: object, *, sole: bool = False, _f8: np.dtype = _F8,
                      _mm: float = MAX_MEAN, _nmm: float = -MAX_MEAN, _mc: float = MAX_COV,
                      _rc: Callable[[object], int] = _getrefcount, _sp: int = _SOLE_PAIR,
                      _sa: int = _SOLE_ARRAY) -> tuple[np.ndarray, np.ndarray] | str:
    """The one guard of what ``estimate()`` returned: ``(mean (3,), cov (3, 3))`` as fresh
    float arrays [m, m, rad], or one line saying why it is unusable (not a pair, not
    numbers, wrong shapes, NaN or infinity, covariance not symmetric, not positive
    semi-definite). Cheap (about a microsecond): it runs on every step of every filter.

    ``sole=True`` (the runner, which holds ``est`` in one variable and drops it after): two
    float64 arrays that own their data and that nothing else refers to (reference counts,
    CPython) are returned as they are rather than copied: a filter that builds its estimate
    afresh each step (the EKF, the UKF, the PF) is not copied again; one that returns arrays
    it keeps is. Same values either way.

    The usual case, float64 arrays of 3 and 9 entries, is judged here with float
    comparisons; anything else, and anything the fast path cannot settle, takes the full
    check (:func:`_validate_any`), which names what is wrong. The verdicts are the same
    (tests/hosting/test_guard_fast_path.py): the shapes are those of the unpacking (any other shape
    of 3 and 9 entries fails it, or leaves lists that no float comparison takes: TypeError);
    an exactly symmetric covariance whose entries lie within [-s, s], s its largest diagonal
    entry with 1e-12 <= s <= MAX_COV, has every entry finite (a NaN fails every comparison)
    and s as its largest |entry|, so only the PSD test is left; otherwise a finite sum of
    the entries proves them finite (a NaN or an infinity would make it NaN or infinite), and
    one that overflows goes the long way too.

    The keyword arguments after ``sole`` are not for callers: the constants of the fast
    path, bound once (locals cost less than globals on a path that runs every step)."""
    if (type(est) is tuple or isinstance(est, tuple | list)) and len(est) == 2:
        m0, c0 = est
        if (type(m0) is np.ndarray and type(c0) is np.ndarray and m0.dtype is _f8 and c0.dtype is _f8
                and m0.size == 3 and c0.size == 9):
            try:
                (a, b, d), (b2, e, f), (d2, f2, g) = c0.tolist()
                x, y, t = m0.tolist()
                # NaN, infinity or a diverged mean fail here: the full check says which
                if _nmm <= x <= _mm and _nmm <= y <= _mm and _nmm <= t <= _mm:
                    s = a if a >= e else e  # max(a, e, g) (a NaN fails below either way)
                    if g > s:
                        s = g
                    ns = -s
                    if (b == b2 and d == d2 and f == f2 and 1e-12 <= s <= _mc and a >= ns and e >= ns
                            and g >= ns and ns <= b <= s and ns <= d <= s and ns <= f <= s):
                        # _not_psd inline: its tolerance is 1e-9 * s here (0.5 * (b + b) == b exactly)
                        tol = 1e-9 * s
                        a, e, g = a + tol, e + tol, g + tol
                        if a <= 0.0:
                            return _NOT_PSD
                        e1 = e - b * (b / a)
                        if e1 <= 0.0:
                            return _NOT_PSD
                        f1 = f - d * (b / a)
                        if g - d * (d / a) - f1 * (f1 / e1) <= 0.0:
                            return _NOT_PSD
                        if (sole and _rc(m0) <= _sa and _rc(c0) <= _sa and _rc(est) <= _sp
                                and m0.base is None and c0.base is None):
                            return m0, c0
                        return m0.copy(), c0.copy()
                    if math.isfinite(a + b + d + b2 + e + f + d2 + f2 + g):
                        scale = max(abs(a), abs(b), abs(d), abs(b2), abs(e), abs(f), abs(d2), abs(f2),
                                    abs(g), 1e-12)
                        if scale > MAX_COV:
                            return _DIVERGED
                        if max(abs(b - b2), abs(d - d2), abs(f - f2)) > 1e-6 * scale:
                            return "covariance is not symmetric"
                        if _not_psd(a, 0.5 * (b + b2), 0.5 * (d + d2), e, 0.5 * (f + f2), g):
                            return _NOT_PSD
                        if (sole and _rc(m0) <= _sa and _rc(c0) <= _sa and _rc(est) <= _sp
                                and m0.base is None and c0.base is None):
                            return m0, c0
                        return m0.copy(), c0.copy()
            except (TypeError, ValueError):  # not (3,) and (3, 3): the full check names the shapes
                pass
    return _validate_any(est)


#: The one line of a diverged estimate, in every front end (``run``, ``eval``, ``check``,
#: ``grade``, the window): a mean beyond :data:`MAX_MEAN` or a covariance entry over
#: :data:`MAX_COV`. The one divergence rule: ``eval`` and ``grade`` once used 1e100.
DIVERGED = (f"estimate() returned a mean beyond {MAX_MEAN:g} or a covariance entry over {MAX_COV:g} "
            "(diverged)")
#: The one line of an estimate whose covariance rules out the error it had (its NEES
#: ``e^T P^-1 e`` against the truth is infinite or NaN: a singular covariance with the error
#: outside its range). Judged where the truth is (``run``, ``eval``, ``grade`` and ``check``
#: score it, never the filter's process); such a filter is never "ok".
NEES_NOT_FINITE = ("estimate() returned a covariance that leaves no room for the estimate's error "
                   "(NEES not finite)")
_DIVERGED = DIVERGED
_NOT_PSD = "covariance is not positive semi-definite"


def _validate_any(est: object) -> tuple[np.ndarray, np.ndarray] | str:
    """:func:`validate_estimate` for anything a filter may return."""
    if not isinstance(est, tuple | list) or len(est) != 2:
        return f"estimate() returned {_type_name(est)}, expected a (mean, cov) pair"
    mean, cov = _as_numbers(est[0]), _as_numbers(est[1])
    if mean is None or cov is None:
        return (f"estimate() returned {_type_name(est[0])} and {_type_name(est[1])}, "
                "expected arrays of numbers")
    if mean.shape != (3,) or cov.shape != (3, 3):
        return f"estimate() returned shapes {mean.shape} and {cov.shape}, expected (3,) and (3, 3)"
    c = cov.tolist()
    m = mean.tolist()
    if not all(map(math.isfinite, (*m, *c[0], *c[1], *c[2]))):
        return "estimate() returned NaN or infinity"
    (a, b, d), (b2, e, f), (d2, f2, g) = c
    scale = max(abs(a), abs(b), abs(d), abs(b2), abs(e), abs(f), abs(d2), abs(f2), abs(g), 1e-12)
    if scale > MAX_COV or max(abs(m[0]), abs(m[1]), abs(m[2])) > MAX_MEAN:
        return DIVERGED
    if max(abs(b - b2), abs(d - d2), abs(f - f2)) > 1e-6 * scale:
        return "covariance is not symmetric"
    b, d, f = 0.5 * (b + b2), 0.5 * (d + d2), 0.5 * (f + f2)
    if _not_psd(a, b, d, e, f, g):
        return "covariance is not positive semi-definite"
    return mean, cov


def check_estimate(mean: object, cov: object) -> str | None:
    """Why an estimate is unusable (see :func:`validate_estimate`), or None."""
    r = validate_estimate((mean, cov))
    return r if isinstance(r, str) else None


def validate_belief(bel: object) -> Belief | str:
    """The guard of what ``belief()`` returned, for drawing: a belief whose arrays are float,
    finite and of the right shapes, or one line saying why not.

    GaussianBelief: as :func:`validate_estimate`. ParticleBelief: poses (N, 3) [m, m, rad]
    with N >= 1, weights (N,) >= 0 with a positive sum. GridBelief: prob 2-D >= 0 with a
    positive sum, origin two finite numbers [m], cell > 0 [m].
    """
    if isinstance(bel, GaussianBelief):
        r = validate_estimate((bel.mean, bel.cov))
        if isinstance(r, str):
            return "belief(): " + r.replace("estimate() returned", "Gaussian has")
        return GaussianBelief(*r)
    if isinstance(bel, ParticleBelief):
        poses, w = _as_numbers(bel.poses), _as_numbers(bel.weights)
        if poses is None or w is None:
            return "belief(): particle poses or weights are not arrays of numbers"
        if poses.ndim != 2 or poses.shape[1] != 3 or poses.shape[0] < 1 or w.shape != (len(poses),):
            return (f"belief(): particle poses {poses.shape} and weights {w.shape}, "
                    "expected (N, 3) and (N,)")
        if not (np.isfinite(poses).all() and np.isfinite(w).all()):
            return "belief(): particles with NaN or infinity"
        if (w < 0).any() or not w.sum() > 0:
            return "belief(): particle weights must be >= 0 with a positive sum"
        return ParticleBelief(poses, w)
    if isinstance(bel, GridBelief):
        prob = _as_numbers(bel.prob)
        origin = _as_numbers(bel.origin)
        cell = _as_numbers(bel.cell)
        if prob is None or origin is None or cell is None or prob.ndim != 2 or origin.shape != (2,) \
                or cell.shape != () or min(prob.shape) < 1:
            return "belief(): grid needs prob (nx, ny), origin (x, y) [m] and a cell size [m]"
        if not (np.isfinite(prob).all() and np.isfinite(origin).all() and math.isfinite(float(cell))):
            return "belief(): grid with NaN or infinity"
        if (prob < 0).any() or not prob.sum() > 0 or not float(cell) > 0:
            return "belief(): grid probabilities must be >= 0 with a positive sum, cell > 0"
        return GridBelief(prob, (float(origin[0]), float(origin[1])), float(cell))
    return f"belief() returned {_type_name(bel)}, expected a GaussianBelief, ParticleBelief or GridBelief"


def estimate_arrays(est: object) -> tuple[np.ndarray, np.ndarray] | str:
    """What ``estimate()`` returned as ``(mean (3,), cov (3, 3))`` float arrays whose values
    are judged later, over the whole run (``evaluation.montecarlo.finish_filter``), or the
    guard's one line for anything of the wrong form. Arrays of the right shapes pass as
    they are (NaN included); anything else is judged in full by :func:`validate_estimate`."""
    if isinstance(est, tuple | list) and len(est) == 2:
        m, c = est
        if (type(m) is np.ndarray and type(c) is np.ndarray and m.shape == (3,)
                and c.shape == (3, 3) and m.dtype.kind in "biuf" and c.dtype.kind in "biuf"):
            return m.astype(float, copy=False), c.astype(float, copy=False)
    return validate_estimate(est)


def shape_text(mean: object, cov: object) -> str:
    """The one plain message for an estimate of the wrong shape, the same in every front end
    (``eval``, ``grade``, ``check``, the window), instead of numpy's "could not broadcast"."""
    def shape(x: object) -> str:
        try:
            return str(np.shape(x))  # type: ignore[call-overload]
        except Exception:  # an object numpy cannot even look at
            return type(x).__name__
    return f"estimate() returned shapes {shape(mean)} and {shape(cov)}, expected (3,) and (3, 3)"


__all__ = ["DIVERGED", "MAX_COV", "MAX_MEAN", "NEES_NOT_FINITE", "check_estimate", "estimate_arrays",
           "shape_text", "validate_belief", "validate_estimate"]
