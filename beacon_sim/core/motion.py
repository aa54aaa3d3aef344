"""The velocity motion model (seeds 000, 001, 003) and its Jacobians.

``x' = x + v dt cos(theta); y' = y + v dt sin(theta); theta' = theta + omega dt``

All functions accept a single pose of shape (3,) or a batch of shape (N, 3).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from beacon_sim.core import portable_math as pm
from beacon_sim.core.angles import wrap


def move(pose, v, omega, dt):
    """Apply the velocity model to ``pose`` (shape (3,) or (N, 3)); heading wrapped.

    ``v`` [m/s] and ``omega`` [rad/s] may be scalars or arrays of shape (N,) (one per pose,
    as a particle filter samples them).
    """
    pose = np.asarray(pose, dtype=float)
    if pose.ndim == 1 and np.ndim(v) == 0 and np.ndim(omega) == 0:  # one pose: no broadcasting
        theta = pose[2]
        out = np.empty(3)
        out[0] = pose[0] + v * dt * np.cos(theta)
        out[1] = pose[1] + v * dt * np.sin(theta)
        out[2] = wrap(theta + omega * dt)
        return out
    theta = pose[..., 2]
    out = np.empty(np.broadcast_shapes(pose.shape, (*np.shape(v), 3)), dtype=float)
    out[..., 0] = pose[..., 0] + v * dt * np.cos(theta)
    out[..., 1] = pose[..., 1] + v * dt * np.sin(theta)
    out[..., 2] = wrap(theta + omega * dt)
    return out


def move_portable(pose, v, omega, dt):
    """:func:`move` with the portable kernels (core/portable_math.py): the truth's motion,
    the same bits on every machine. Filters use :func:`move` (numpy's fast kernels, equal
    to within a few ulp: tests/core/test_portable_math.py)."""
    pose = np.asarray(pose, dtype=float)
    if pose.ndim == 1 and np.ndim(v) == 0 and np.ndim(omega) == 0:
        theta = pose[2]
        s, c = pm.sincos1(float(theta))
        out = np.empty(3)
        out[0] = pose[0] + v * dt * c
        out[1] = pose[1] + v * dt * s
        out[2] = wrap(theta + omega * dt)
        return out
    thetas = pose[..., 2]
    sa, ca = pm.sincos(thetas)
    out = np.empty(np.broadcast_shapes(pose.shape, (*np.shape(v), 3)), dtype=float)
    out[..., 0] = pose[..., 0] + v * dt * ca
    out[..., 1] = pose[..., 1] + v * dt * sa
    out[..., 2] = wrap(thetas + omega * dt)
    return out


def jacobian_state(pose, v, dt):
    """F = d move / d pose, shape (3, 3), evaluated at ``pose`` (seed 000 eq. 9)."""
    theta = float(pose[2])
    return np.array(
        [
            [1.0, 0.0, -v * dt * np.sin(theta)],
            [0.0, 1.0, v * dt * np.cos(theta)],
            [0.0, 0.0, 1.0],
        ]
    )


def jacobian_control(pose, dt):
    """B = d move / d (v, omega), shape (3, 2); also the KF's control matrix (seed 003)."""
    theta = float(pose[2])
    return np.array(
        [
            [dt * np.cos(theta), 0.0],
            [dt * np.sin(theta), 0.0],
            [0.0, dt],
        ]
    )


#: The slip models (``MotionNoise.slip``). "scaled": the constant noise terms (``v_std``,
#: ``omega_std``, ``pose_std``) fade to zero as the command does, so a stopped robot does not
#: move. "legacy": they apply whatever the command, even at v = omega = 0 (before
#: 0.3.0; recordings without a "slip_model" header key replay with it).
SLIP_MODELS = ("scaled", "legacy")
#: Under the "scaled" model the constant terms are at full strength once
#: ``|v| / FULL_SLIP_V + |omega| / FULL_SLIP_OMEGA >= 1`` [m/s, rad/s] (half the keyboard's
#: smallest steps: any key-driven motion slips fully), and scale linearly below.
FULL_SLIP_V = 0.05
FULL_SLIP_OMEGA = 0.1


@dataclass(frozen=True)
class MotionNoise:
    """Noise on the executed velocity command, and optional additive pose noise per step.

    The standard deviation of the executed speed is ``g v_std + v_frac * |v|`` [m/s] and of
    the executed turn rate ``g omega_std + omega_frac * |omega|`` [rad/s] (seed 002 uses
    25 % of v). ``g pose_std`` [m, m, rad] is white noise added to the pose every step. The
    gain ``g`` (:meth:`slip_gain`) is 0 at v = omega = 0 and 1 once the robot moves at all
    (``slip = "scaled"``), or always 1 (``slip = "legacy"``).
    """

    v_std: float = 0.0
    v_frac: float = 0.0
    omega_std: float = 0.0
    omega_frac: float = 0.0
    pose_std: tuple[float, float, float] = (0.0, 0.0, 0.0)
    slip: str = "scaled"

    def slip_gain(self, v, omega):
        """The factor ``g`` on the constant terms for a command (arrays broadcast): 1.0
        (legacy), or ``min(1, |v| / FULL_SLIP_V + |omega| / FULL_SLIP_OMEGA)`` (scaled)."""
        if self.slip == "legacy":
            return 1.0
        if type(v) is float and type(omega) is float:
            # one command on floats (numpy on scalars costs ~4 us a call): the same
            # minimums, NaN kept as np.minimum keeps it
            av, aw = abs(v), abs(omega)
            t = (FULL_SLIP_V if av >= FULL_SLIP_V else av) / FULL_SLIP_V \
                + (FULL_SLIP_OMEGA if aw >= FULL_SLIP_OMEGA else aw) / FULL_SLIP_OMEGA
            return 1.0 if t >= 1.0 else t
        # each term capped at 1 before dividing: no overflow for a wild command
        g = np.minimum(1.0, np.minimum(np.abs(v), FULL_SLIP_V) / FULL_SLIP_V
                       + np.minimum(np.abs(omega), FULL_SLIP_OMEGA) / FULL_SLIP_OMEGA)
        return float(g) if np.ndim(g) == 0 else g

    def control_std(self, v, omega):
        """Standard deviations ``(sigma_v, sigma_omega)`` for a command (arrays broadcast)."""
        g = self.slip_gain(v, omega)
        if type(v) is float and type(omega) is float:
            # one command on floats: the same operations, returned as np.float64 as below
            return (np.float64(g * self.v_std + self.v_frac * abs(v)),
                    np.float64(g * self.omega_std + self.omega_frac * abs(omega)))
        return (
            g * self.v_std + self.v_frac * np.abs(v),
            g * self.omega_std + self.omega_frac * np.abs(omega),
        )

    def pose_std_at(self, v, omega) -> np.ndarray:
        """The additive pose noise [m, m, rad] for a command: shape (3,), or (N, 3) for
        commands of shape (N,)."""
        g = self.slip_gain(v, omega)
        ps = np.asarray(self.pose_std, dtype=float)
        return ps * g if np.ndim(g) == 0 else np.asarray(g)[:, None] * ps

    def control_cov(self, v, omega):
        """M = diag(sigma_v^2, sigma_omega^2), shape (2, 2) [m^2/s^2, rad^2/s^2]."""
        sv, sw = self.control_std(v, omega)
        return np.diag([float(sv) ** 2, float(sw) ** 2])

    def process_cov(self, pose, v, omega, dt):
        """Process noise covariance in state space, shape (3, 3):
        ``B M B^T + diag(pose_std_at(v, omega)^2)``."""
        B = jacobian_control(pose, dt)
        return B @ self.control_cov(v, omega) @ B.T + np.diag(np.square(self.pose_std_at(v, omega)))


def with_slip(noise: MotionNoise, model: str) -> MotionNoise:
    """``noise`` under the slip model ``model`` (one of :data:`SLIP_MODELS`)."""
    if model not in SLIP_MODELS:
        raise ValueError(f"slip model {model!r}: expected one of {', '.join(SLIP_MODELS)}")
    return noise if noise.slip == model else replace(noise, slip=model)
