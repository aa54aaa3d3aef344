"""Where on the floor a distance reading puts the receiver, in metres, for the window:
the circle of a range, the curve of a range difference (a hyperbola when the beacons are at
the receiver's height), and the HDOP of the beacon layout over the floor.

Beacons are ``height`` metres above the receiver (core/ceiling_beacons.py). A range r puts
the receiver on the circle of horizontal radius ``sqrt(r^2 - h^2)`` about the beacon. A
difference d against a reference puts it on ``{p : r_b(p) - r_ref(p) = d}``, traced here from
a point near it by steps along the curve (each corrected back onto it by a Newton step).
"""

from __future__ import annotations

import math

import numpy as np

from beacon_sim.core.geometry import hdop
from beacon_sim.core.trilateration import tdoa_hdop


def range_circle(bxy, measured: float, height: float, n: int = 96) -> np.ndarray | None:
    """Outline (n, 2) [m] of the floor points at range ``measured`` from the beacon at
    ``bxy``; None when the range is shorter than the height (no such point)."""
    r2 = measured * measured - height * height
    if not r2 > 0.0:
        return None
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    return np.asarray(bxy, dtype=float) + math.sqrt(r2) * np.stack([np.cos(t), np.sin(t)], 1)


def _f_grad(px: float, py: float, b, ref, d: float, h2: float) -> tuple[float, float, float]:
    """The residual ``r_b - r_ref - d`` [m] at (px, py) and its gradient (x, y), in plain
    floats: the tracer calls this some thousands of times a curve (numpy's per-call cost
    would be most of it)."""
    ux, uy = px - b[0], py - b[1]
    vx, vy = px - ref[0], py - ref[1]
    rb = math.sqrt(ux * ux + uy * uy + h2)
    rr = math.sqrt(vx * vx + vy * vy + h2)
    mb, mr = max(rb, 1e-12), max(rr, 1e-12)
    return rb - rr - d, ux / mb - vx / mr, uy / mb - vy / mr


def _onto(px: float, py: float, b, ref, d, h2) -> tuple[float, float] | None:
    """Newton steps from (px, py) onto the curve (``_f_grad`` written out: the hot loop)."""
    bx, by = b
    rx, ry = ref
    for _ in range(20):
        ux, uy = px - bx, py - by
        vx, vy = px - rx, py - ry
        rb = math.sqrt(ux * ux + uy * uy + h2)
        rr = math.sqrt(vx * vx + vy * vy + h2)
        mb, mr = max(rb, 1e-12), max(rr, 1e-12)
        f, gx, gy = rb - rr - d, ux / mb - vx / mr, uy / mb - vy / mr
        gg = gx * gx + gy * gy
        if gg < 1e-18:
            return None
        k = f / gg
        px, py = px - k * gx, py - k * gy
        if abs(f) < 1e-9:
            return px, py
    return (px, py) if abs(_f_grad(px, py, b, ref, d, h2)[0]) < 1e-6 else None


def difference_curve(ref_xy, b_xy, d: float, height: float, near_xy, length: float,
                     step: float | None = None) -> np.ndarray | None:
    """Points (k, 2) [m] of the curve ``r_b - r_ref = d`` through the point nearest
    ``near_xy``, ``length`` metres each way; None when no such curve is near (|d| larger
    than the beacons' separation allows, or a flat spot)."""
    b = tuple(float(v) for v in np.asarray(b_xy, dtype=float)[:2])
    ref = tuple(float(v) for v in np.asarray(ref_xy, dtype=float)[:2])
    h2 = height * height
    step = step or length / 80.0
    near = np.asarray(near_xy, dtype=float)
    p0 = _onto(float(near[0]), float(near[1]), b, ref, d, h2)
    if p0 is None:
        return None
    sides = []
    for sign in (1.0, -1.0):
        pts, (px, py) = [], p0
        for _ in range(int(length / step)):
            _, gx, gy = _f_grad(px, py, b, ref, d, h2)
            tx, ty = -gy * sign, gx * sign
            nt = math.hypot(tx, ty)
            if nt < 1e-12:
                break
            q = _onto(px + step * tx / nt, py + step * ty / nt, b, ref, d, h2)
            if q is None:
                break
            px, py = q
            pts.append(q)
        sides.append(pts)
    return np.array(sides[1][::-1] + [p0] + sides[0], dtype=float)


def floor_hdop(kind: str, bounds, bxy, height: float, nx: int = 64, ny: int = 48
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """HDOP over the floor: cell centres ``xs`` (nx,), ``ys`` (ny,) [m] and HDOP (ny, nx) of
    a fix from every beacon: TDOA (``kind`` "tdoa" / "tdoa_fix") or ranges (any other)."""
    xmin, ymin, xmax, ymax = bounds
    xs = xmin + (np.arange(nx) + 0.5) * (xmax - xmin) / nx
    ys = ymin + (np.arange(ny) + 0.5) * (ymax - ymin) / ny
    X, Y = np.meshgrid(xs, ys)
    pts = np.column_stack([X.ravel(), Y.ravel()])
    if kind in ("tdoa", "tdoa_fix"):
        val = tdoa_hdop(pts, bxy, height)
    else:
        val = np.asarray(hdop(pts, bxy, height))
    return xs, ys, np.asarray(val).reshape(ny, nx)


__all__ = ["difference_curve", "floor_hdop", "range_circle"]
