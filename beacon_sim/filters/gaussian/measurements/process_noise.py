"""The velocity motion model's process noise, on arrays (one run or R runs), and the
symmetric 3x3 covariance as its six entries and back."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from beacon_sim.core.motion import MotionNoise


def process_cov_terms(noise: MotionNoise, theta: Any, c: Any, s: Any, v: Any, omega: Any, dt: float
                      ) -> tuple[Any, ...]:
    """``(q00, q01, q02, q11, q12, q22)`` of ``noise.process_cov(pose, v, omega, dt)`` at the
    heading ``theta`` [rad] (c, s its cos and sin), as floats or as arrays (R,).

    Q = B M B^T + diag(pose_std^2) with B = [[dt cos, 0], [dt sin, 0], [0, dt]] and
    M = diag(sigma_v^2, sigma_omega^2), written out for a plain ``MotionNoise``; any other
    noise object is asked for its ``process_cov`` (floats only).
    """
    if type(noise) is not MotionNoise:
        q = noise.process_cov(np.array([0.0, 0.0, theta]), v, omega, dt).tolist()
        return q[0][0], q[0][1], q[0][2], q[1][1], q[1][2], q[2][2]
    g = noise.slip_gain(v, omega)  # slip scales with the command (1.0 while moving)
    sv = g * noise.v_std + noise.v_frac * abs(v)
    sw = g * noise.omega_std + noise.omega_frac * abs(omega)
    qv = dt * dt * sv * sv
    p0, p1, p2 = (g * p for p in noise.pose_std)
    return (qv * c * c + p0 * p0, qv * c * s, 0.0, qv * s * s + p1 * p1, 0.0,
            dt * dt * sw * sw + p2 * p2)


def cov_entries(P: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                         np.ndarray]:
    """The six distinct entries (p00, p01, p02, p11, p12, p22) of P (..., 3, 3), as views."""
    return P[..., 0, 0], P[..., 0, 1], P[..., 0, 2], P[..., 1, 1], P[..., 1, 2], P[..., 2, 2]


def cov_matrix(p: Sequence[Any]) -> np.ndarray:
    """The symmetric matrices (R, 3, 3) with the six entries ``p`` (arrays (R,) or floats)."""
    p00, p01, p02, p11, p12, p22 = p
    rows = np.empty((9, *np.shape(p00)))  # row-major entries, one row each (fast to fill)
    rows[0] = p00
    rows[1] = rows[3] = p01
    rows[2] = rows[6] = p02
    rows[4] = p11
    rows[5] = rows[7] = p12
    rows[8] = p22
    return rows.T.reshape(-1, 3, 3)


__all__ = ["cov_entries", "cov_matrix", "process_cov_terms"]
