"""The simulation's transcendental maths, the same bits on every machine.

numpy's float64 ``sin``, ``exp``, ``log``, ``arctan2``... run different code on different
processors (on x86-64 with AVX-512, SVML kernels that round the last bit differently from the
C library; numpy#23523), and the C library's own ``math.atan2`` differs between glibc,
macOS and Windows, and between glibc's FMA and non-FMA variants. Only ``+ - * /`` and ``sqrt``
are rounded the same by every IEEE-754 machine. The kernels here are built from those alone
(plus exact operations: ``abs``, ``rint``, ``floor``, ``frexp``, ``ldexp``, ``copysign``,
comparisons), so the truth and the readings of a run are the same bits on x86-64 with and
without AVX-512, ARM64, Linux, macOS and Windows (docs/portability.md).

Each kernel comes twice: for numpy arrays (``sin``, ``atan2``...) and for Python floats
(``sin1``, ``atan2_1``...: no array overhead, for one pose a tick). Both do the same IEEE
operations in the same order, so they give the same bits (tests/core/test_portable_math.py holds
them equal, and the kernels within 3 ulp of the C library on random inputs). The polynomials
are near-minimax fits made by ``scripts/fit_portable_math.py``; they are part of the format of
a run: changing one changes every checksum.

Accuracy: within 3 ulp of the C library (itself within 1 ulp of the exact result) for the
arguments a simulation meets (angles |x| < 1e5 rad, finite coordinates); outside that the
result is still portable, less accurate. Infinities as inputs are not handled (NaN
propagates).
"""

from __future__ import annotations

import math

import numpy as np

# -- constants (exact binary values; scripts/fit_portable_math.py derives them) -------------
# pi/2 in three parts of 33 significant bits: k * part is exact for |k| < 2**20 (Cody-Waite).
_PIO2_1, _PIO2_2, _PIO2_3 = 1.5707963267341256, 6.077100506303966e-11, 2.0222662487959506e-21
_TWO_OVER_PI = 0.6366197723675814
# pi, pi/2, pi/4 as the nearest double plus the rest.
_PI_HI, _PI_LO = 3.141592653589793, 1.2246467991473532e-16
_PIO2_HI, _PIO2_LO = 1.5707963267948966, 6.123233995736766e-17
_PIO4_HI, _PIO4_LO = 0.7853981633974483, 3.061616997868383e-17
_TAN_PI_8 = 0.41421356237309515
# ln 2 in two parts, the first of 33 bits: e * _LN2_HI is exact for |e| < 2**20.
_LN2_HI, _LN2_LO = 0.6931471806019545, -4.2009150726810846e-11
_INV_LN2 = 1.4426950408889634
_SQRT_HALF = 0.7071067811865476
_EXP_MAX, _EXP_MIN = 709.782712893384, -745.1332191019412   # exp overflows / underflows to 0

# -- polynomials in z (lowest degree first) --------------------------------------------------
#: sin(r) = r + r z S(z), z = r^2, |r| <= pi/4
_SIN = (-0.1666666666666666, 0.008333333333333231, -0.00019841269841047547,
        2.7557319054798155e-06, -2.5052048675315014e-08, 1.6049205236567765e-10,
        -7.023042637422421e-13)
#: cos(r) = 1 - z/2 + z^2 C(z)
_COS = (0.04166666666666667, -0.0013888888888888933, 2.4801587301936977e-05,
        -2.755731956087051e-07, 2.0876880204510807e-09, -1.1490272620823428e-11,
        5.898235575065915e-14)
#: atan(r) = r + r z A(z), |r| <= tan(pi/8)
_ATAN = (-0.3333333333333335, 0.20000000000000107, -0.14285714285616552, 0.11111111093877468,
         -0.09090907986170181, 0.07692270607802769, -0.06665921649691325, 0.0587283606601755,
         -0.051840169141904494, 0.043346141640916235, -0.028890430699780204,
         0.009904335304580545)
#: exp(r) = 1 + (r + r^2 E(r)), |r| <= ln(2)/2
_EXP = (0.49999999999999983, 0.16666666666666677, 0.04166666666666475, 0.008333333333350611,
        0.0013888888891824607, 0.00019841269756123092, 2.4801577526806667e-05,
        2.7557426570621068e-06, 2.756859674460081e-07, 2.5028489544779975e-08,
        1.6624233290243712e-09)
#: atanh(s) = s + s w T(w), w = s^2, |s| <= 3 - 2 sqrt(2)  (log(m) = 2 atanh((m-1)/(m+1)))
_ATANH = (0.3333333333333332, 0.2000000000000008, 0.14285714285680676, 0.11111111125493811,
          0.0909090583768351, 0.07692664251807213, 0.06646991260816476, 0.06408042485371052)


#: Arrays up to this size go through the float kernels (numpy's per-call cost dominates).
_SMALL = 24


def _poly(z, coef):
    """Horner's rule, highest degree first: the same operations on a float or an array."""
    acc = coef[-1]
    for c in coef[-2::-1]:
        acc = acc * z + c
    return acc


# -- arrays ----------------------------------------------------------------------------------
def _reduce_pio2(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``x = k pi/2 + r`` with |r| <= pi/4 (about); returns (r, k mod 4 as float)."""
    k = np.rint(x * _TWO_OVER_PI)
    r = ((x - k * _PIO2_1) - k * _PIO2_2) - k * _PIO2_3
    q = k - 4.0 * np.floor(k * 0.25)
    return r, q


def _sin_cos_poly(r):
    z = r * r
    s = r + r * z * _poly(z, _SIN)
    c = (1.0 - 0.5 * z) + z * z * _poly(z, _COS)
    return s, c


def sincos(x) -> tuple[np.ndarray, np.ndarray]:
    """``(sin(x), cos(x))`` of an array of angles [rad], portable bits."""
    x = np.asarray(x, dtype=float)
    if x.size <= _SMALL:
        pairs = [sincos1(v) for v in x.ravel().tolist()]
        return (np.array([p[0] for p in pairs]).reshape(x.shape),
                np.array([p[1] for p in pairs]).reshape(x.shape))
    r, q = _reduce_pio2(x)
    s, c = _sin_cos_poly(r)
    odd = (q == 1.0) | (q == 3.0)
    sin = np.where(odd, c, s)
    cos = np.where(odd, s, c)
    sin[q >= 2.0] *= -1.0                    # exact: a sign flip
    cos[(q == 1.0) | (q == 2.0)] *= -1.0
    return sin, cos


def sin(x) -> np.ndarray:
    """Portable ``sin`` of an array [rad]."""
    return sincos(x)[0]


def cos(x) -> np.ndarray:
    """Portable ``cos`` of an array [rad]."""
    return sincos(x)[1]


def atan2(y, x) -> np.ndarray:
    """Portable ``arctan2(y, x)`` [rad] in [-pi, pi], with numpy's signs of zero and pi."""
    y, x = np.broadcast_arrays(np.asarray(y, dtype=float), np.asarray(x, dtype=float))
    if x.size <= _SMALL:
        return np.array([atan2_1(a, b) for a, b in zip(y.ravel().tolist(), x.ravel().tolist(),
                                                         strict=True)]).reshape(x.shape)
    ax, ay = np.abs(x), np.abs(y)
    swap = ay > ax
    num = np.where(swap, ax, ay)
    den = np.where(swap, ay, ax)
    t = np.divide(num, den, out=np.zeros_like(num), where=den != 0.0)
    big = t > _TAN_PI_8
    r = np.where(big, (t - 1.0) / (t + 1.0), t)
    z = r * r
    a = r + r * z * _poly(z, _ATAN)
    a = np.where(big, _PIO4_HI + (a + _PIO4_LO), a)
    a = np.where(swap, _PIO2_HI - (a - _PIO2_LO), a)
    a = np.where(np.signbit(x), _PI_HI - (a - _PI_LO), a)
    return np.copysign(a, y)


def hypot(x, y) -> np.ndarray:
    """Portable ``sqrt(x^2 + y^2)`` (no care for overflow: metres, not 1e154)."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    return np.sqrt(x * x + y * y)


def exp(x) -> np.ndarray:
    """Portable ``exp`` of an array."""
    x = np.asarray(x, dtype=float)
    xc = np.clip(np.where(np.isnan(x), 0.0, x), _EXP_MIN, _EXP_MAX)
    k = np.rint(xc * _INV_LN2)
    r = (xc - k * _LN2_HI) - k * _LN2_LO
    p = 1.0 + (r + r * r * _poly(r, _EXP))
    out = np.ldexp(p, k.astype(np.int64))
    out = np.where(x > _EXP_MAX, np.inf, np.where(x < _EXP_MIN, 0.0, out))
    return np.where(np.isnan(x), x, out)


def log(x) -> np.ndarray:
    """Portable natural ``log`` of an array (-inf at 0, NaN below)."""
    x = np.asarray(x, dtype=float)
    ok = (x > 0.0) & (x < np.inf)
    m, e = np.frexp(np.where(ok, x, 1.0))
    small = m < _SQRT_HALF
    m = np.where(small, m + m, m)
    k = (e - small).astype(float)
    f = m - 1.0
    s = f / (2.0 + f)
    hs = s + s
    w = s * s
    lm = hs + hs * w * _poly(w, _ATANH)
    out = k * _LN2_HI + (k * _LN2_LO + lm)
    return np.where(ok, out, np.where(x == 0.0, -np.inf, np.where(x == np.inf, x, np.nan)))


def log1p(x) -> np.ndarray:
    """Portable ``log(1 + x)``, accurate for small x (Goldberg's correction)."""
    x = np.asarray(x, dtype=float)
    u = 1.0 + x
    d = u - 1.0
    ratio = np.divide(x, d, out=np.ones_like(x), where=d != 0.0)
    return np.where(d == 0.0, x, log(u) * ratio)


def expm1(x) -> np.ndarray:
    """Portable ``exp(x) - 1``, accurate for small x (Kahan's correction)."""
    x = np.asarray(x, dtype=float)
    u = exp(x)
    d = u - 1.0
    lu = log(u)
    fixed = d * np.divide(x, lu, out=np.ones_like(x), where=(lu != 0.0) & (lu != np.inf))
    return np.where(u == 1.0, x, np.where(d == -1.0, -1.0, np.where(u == np.inf, np.inf, fixed)))


# -- Python floats (the same operations, in the same order) ----------------------------------
def sincos1(x: float) -> tuple[float, float]:
    """``(sin(x), cos(x))`` of one angle [rad]: the bits of :func:`sincos`."""
    if not math.isfinite(x):
        return math.nan, math.nan
    k = float(round(x * _TWO_OVER_PI))   # round() is round-half-even, as np.rint
    r = ((x - k * _PIO2_1) - k * _PIO2_2) - k * _PIO2_3
    q = k - 4.0 * math.floor(k * 0.25)
    s, c = _sin_cos_poly(r)
    if q == 0.0:
        return s, c
    if q == 1.0:
        return c, -s
    if q == 2.0:
        return -s, -c
    return -c, s


def sin1(x: float) -> float:
    """Portable ``sin`` of one angle [rad]."""
    return sincos1(x)[0]


def cos1(x: float) -> float:
    """Portable ``cos`` of one angle [rad]."""
    return sincos1(x)[1]


def atan2_1(y: float, x: float) -> float:
    """Portable ``atan2(y, x)`` [rad] of two floats: the bits of :func:`atan2`."""
    ax, ay = abs(x), abs(y)
    swap = ay > ax
    num, den = (ax, ay) if swap else (ay, ax)
    t = 0.0 if den == 0.0 else num / den
    big = t > _TAN_PI_8
    r = (t - 1.0) / (t + 1.0) if big else t
    z = r * r
    a = r + r * z * _poly(z, _ATAN)
    if big:
        a = _PIO4_HI + (a + _PIO4_LO)
    if swap:
        a = _PIO2_HI - (a - _PIO2_LO)
    if math.copysign(1.0, x) < 0.0:
        a = _PI_HI - (a - _PI_LO)
    return math.copysign(a, y)


def hypot1(x: float, y: float) -> float:
    """Portable ``sqrt(x^2 + y^2)`` of two floats: the bits of :func:`hypot`."""
    return math.sqrt(x * x + y * y)
