"""Derive the constants and polynomials of beacon_sim/core/portable_math.py.

    python scripts/fit_portable_math.py

Prints the split constants (pi/2 and ln 2 in parts of 33 bits, computed exactly with
``decimal``) and the polynomial coefficients: Chebyshev least-squares fits (near-minimax) of
each kernel's correction term on its reduced interval, against its Taylor series summed in
float64 (which converges fast there). The printed values are the ones portable_math.py holds;
they define the simulation's bits, so a change to them changes every checksum
(docs/portability.md).
"""

from __future__ import annotations

import math
from decimal import Decimal, getcontext

import numpy as np
from numpy.polynomial import Chebyshev, Polynomial

getcontext().prec = 60
PI = Decimal("3.14159265358979323846264338327950288419716939937510582097494459")
LN2 = Decimal("0.693147180559945309417232121458176568075500134360255254120680009")


def parts(v: Decimal, bits: int, n: int) -> list[float]:
    """``v`` as ``n`` doubles, each but the last rounded to ``bits`` significant bits."""
    out, rest = [], v
    for _ in range(n - 1):
        e = math.frexp(float(rest))[1]
        scale = Decimal(2) ** (bits - e)
        hi = (rest * scale).to_integral_value(rounding="ROUND_HALF_EVEN") / scale
        assert Decimal(float(hi)) == hi
        out.append(float(hi))
        rest -= hi
    out.append(float(rest))
    return out


def series(z: np.ndarray, coef, n: int) -> np.ndarray:
    """``sum_k coef(k) z^k`` for k < n, smallest terms first."""
    out = np.zeros_like(z)
    for k in reversed(range(n)):
        out += coef(k) * z**k
    return out


def fit(name: str, a: float, b: float, ref, deg: int) -> None:
    n = 4000
    t = np.cos(np.pi * (np.arange(n) + 0.5) / n)            # Chebyshev nodes
    z = 0.5 * (a + b) + 0.5 * (b - a) * t
    c = Chebyshev.fit(z, ref(z), deg, domain=[a, b]).convert(kind=Polynomial, domain=[-1, 1],
                                                             window=[-1, 1]).coef
    zz = np.linspace(a, b, 20001)
    err = np.max(np.abs(np.polynomial.polynomial.polyval(zz, c) - ref(zz))) / np.max(np.abs(ref(zz)))
    print(f"{name} = ({', '.join(repr(float(x)) for x in c)})  # degree {deg}, rel. error {err:.1e}")


def main() -> None:
    print("_PIO2_1, _PIO2_2, _PIO2_3 =", ", ".join(map(repr, parts(PI / 2, 33, 3))))
    print("_LN2_HI, _LN2_LO =", ", ".join(map(repr, parts(LN2, 33, 2))))
    for name, v in (("_PI", PI), ("_PIO2", PI / 2), ("_PIO4", PI / 4)):
        hi = float(v)
        print(f"{name}_HI, {name}_LO = {hi!r}, {float(v - Decimal(hi))!r}")
    q = (math.pi / 4) ** 2
    fit("_SIN", 0.0, q, lambda z: series(z, lambda k: (-1) ** (k + 1) / math.factorial(2 * k + 3), 25), 6)
    fit("_COS", 0.0, q, lambda z: series(z, lambda k: (-1) ** k / math.factorial(2 * k + 4), 25), 6)
    fit("_ATAN", 0.0, math.tan(math.pi / 8) ** 2,
        lambda z: series(z, lambda k: (-1) ** (k + 1) / (2 * k + 3), 80), 11)
    fit("_EXP", -0.5 * math.log(2), 0.5 * math.log(2),
        lambda r: series(r, lambda k: 1.0 / math.factorial(k + 2), 25), 10)
    fit("_ATANH", 0.0, (3 - 2 * math.sqrt(2)) ** 2, lambda w: series(w, lambda k: 1.0 / (2 * k + 3), 80), 7)


if __name__ == "__main__":
    main()
