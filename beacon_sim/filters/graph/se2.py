"""Poses in the plane, as g2o writes them: ``[x, y, theta]`` [m, m, rad], arrays (..., 3).

``compose(a, b)`` is a * b (b expressed in a's frame put in the world), ``between(a, b)`` is
a^-1 * b (b seen from a), headings wrapped to [-pi, pi).
"""

from __future__ import annotations

import numpy as np

from beacon_sim.core.angles import wrap


def rotation(theta: np.ndarray) -> np.ndarray:
    """R(theta), shape (..., 2, 2)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


def compose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a * b: pose b given in a's frame, in a's parent frame."""
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a[..., 0] + c * b[..., 0] - s * b[..., 1]
    out[..., 1] = a[..., 1] + s * b[..., 0] + c * b[..., 1]
    out[..., 2] = wrap(a[..., 2] + b[..., 2])
    return out


def between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a^-1 * b: pose b seen from pose a."""
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    dx, dy = b[..., 0] - a[..., 0], b[..., 1] - a[..., 1]
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = c * dx + s * dy
    out[..., 1] = -s * dx + c * dy
    out[..., 2] = wrap(b[..., 2] - a[..., 2])
    return out


__all__ = ["between", "compose", "rotation"]
