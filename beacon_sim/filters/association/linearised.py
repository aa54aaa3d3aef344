"""Readings set against beacons for a Gaussian pose belief: the innovation of every reading
against every beacon (:func:`linearise`, :class:`Linearised`), the chi-square gate
(:func:`gate`), the joint NIS of a pairing (:func:`joint_nis`) and the result of a
Gaussian method (:class:`Association`). Readings ``z`` (m, d) in the robot frame [m, rad],
beacons ``beacon_xy`` (n, 2) in the world frame [m], belief mean (3,) and P (3, 3)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from beacon_sim.core import measurement_models as mm
from beacon_sim.core.angles import wrap
from beacon_sim.core.metrics import chi2_quantile
from beacon_sim.core.sensor_kinds import dims

#: The reading kinds that need association and the width of one row.
READING_DIMS = {k: dims(k) for k in ("bearing", "range_bearing")}


#: Default probability that a true pairing passes the gate (and the joint test).
GATE_PROB = 0.99


#: A pairing: (reading index, beacon row index) pairs, in reading order.
Pairing = tuple[tuple[int, int], ...]


@dataclass(frozen=True)
class Association:
    """For each reading, the beacon it was given to (what ``associations()`` reports).

    Attributes
    ----------
    beacon_ids : tuple of (int or None), length m
        The ID of the beacon each reading was associated with; None: no beacon (clutter).
    method : str
        ``"nn"``, ``"jcbb"``, or ``"nn-fallback"`` (JCBB hit its node cap: nearest neighbour).
    joint_nis : float
        Joint NIS of the pairs (with the cross terms; 0 when nothing is paired).
    dof : int
        Degrees of freedom of ``joint_nis``: paired readings times the reading width.
    nodes : int
        Search nodes JCBB visited (0 for nearest neighbour).
    """

    beacon_ids: tuple[int | None, ...]
    method: str
    joint_nis: float = 0.0
    dof: int = 0
    nodes: int = 0

    @property
    def n_paired(self) -> int:
        """How many readings were given a beacon."""
        return sum(b is not None for b in self.beacon_ids)


@dataclass(frozen=True, eq=False)
class Linearised:
    """Every reading against every beacon, linearised at the mean.

    Attributes
    ----------
    kind : str
        ``"bearing"`` or ``"range_bearing"``.
    nu : ndarray, shape (m, n, d)
        Innovations ``z_i - h_j(mean)`` [m, rad]; bearing residuals wrapped.
    H : ndarray, shape (n, d, 3)
        Jacobian of beacon j's expected reading with respect to the pose.
    P : ndarray, shape (3, 3)
        Pose covariance [m^2, m^2, rad^2].
    r : ndarray, shape (d,)
        Reading noise variances (diagonal R) [m^2, rad^2].
    S : ndarray, shape (n, d, d)
        Innovation covariance of one reading paired with beacon j.
    d2 : ndarray, shape (m, n)
        Squared Mahalanobis distances; ``inf`` where undefined (beacon on the robot).
    Z : ndarray, shape (n, d, d), optional
        Each candidate's own noise when it is not just ``diag(r)``: a mapped landmark's
        ``Hm C Hm^T + R`` (FastSLAM, :func:`linearised_landmarks`). None: ``diag(r)``.
    """

    kind: str
    nu: np.ndarray
    H: np.ndarray
    P: np.ndarray
    r: np.ndarray
    S: np.ndarray
    d2: np.ndarray
    Z: np.ndarray | None = None

    @property
    def dim(self) -> int:
        """Width d of one reading."""
        return READING_DIMS[self.kind]


def check_readings(kind: str, z: np.ndarray, beacon_xy: np.ndarray, reading_std: Sequence[float]
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    if kind not in READING_DIMS:
        raise ValueError(f"association: kind {kind!r} is not one of {sorted(READING_DIMS)}")
    d = READING_DIMS[kind]
    z = np.asarray(z, dtype=float).reshape(-1, d)
    xy = np.asarray(beacon_xy, dtype=float).reshape(-1, 2)
    r = np.asarray(reading_std, dtype=float).reshape(-1) ** 2
    if r.shape != (d,):
        raise ValueError(f"association: reading_std for {kind!r} needs {d} values, got {r.size}")
    if not np.all(np.isfinite(r) & (r > 0.0)):
        raise ValueError(f"association: reading_std must be finite and > 0, got {list(np.sqrt(r))}")
    return z, xy, r


def expected(kind: str, pose: np.ndarray, beacon_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Expected readings (n, d) and their Jacobians (n, d, 3) of every beacon from ``pose``."""
    if kind == "bearing":
        return mm.bearing(pose, beacon_xy)[:, None], mm.bearing_jacobian(pose, beacon_xy)[:, None, :]
    return mm.range_bearing(pose, beacon_xy), mm.range_bearing_jacobian(pose, beacon_xy)


def residual(kind: str, z: np.ndarray, zhat: np.ndarray) -> np.ndarray:
    """``z - zhat`` with the bearing column (the last one) wrapped to [-pi, pi)."""
    nu = np.asarray(z, dtype=float) - np.asarray(zhat, dtype=float)
    nu[..., -1] = wrap(nu[..., -1])
    return nu


def linearise(kind: str, z: np.ndarray, mean: np.ndarray, cov: np.ndarray,
              beacon_xy: np.ndarray, reading_std: Sequence[float]) -> Linearised:
    """Innovations, S and squared Mahalanobis distances of every (reading, beacon) pair.

    Parameters
    ----------
    kind : ``"bearing"`` or ``"range_bearing"``
    z : ndarray, shape (m, d) [m, rad]
    mean : ndarray, shape (3,) [m, m, rad]
    cov : ndarray, shape (3, 3)
    beacon_xy : ndarray, shape (n, 2) [m]
    reading_std : the sensor's ``reading_std()``: ``[sb]`` or ``[sr, sb]`` [m, rad]
    """
    z, xy, r = check_readings(kind, z, beacon_xy, reading_std)
    mean = np.asarray(mean, dtype=float)
    P = np.asarray(cov, dtype=float)
    if mean.shape != (3,) or P.shape != (3, 3):
        raise ValueError(f"association: mean must have shape (3,) and cov (3, 3), got {mean.shape} "
                         f"and {P.shape}")
    with np.errstate(divide="ignore", invalid="ignore"):
        zhat, H = expected(kind, mean, xy)
        nu = residual(kind, z[:, None, :], zhat[None, :, :])
        S = H @ P @ H.transpose(0, 2, 1) + np.diag(r)
        ok = np.all(np.isfinite(S), axis=(1, 2))
        S_safe = np.where(ok[:, None, None], S, np.eye(r.size))
        w = np.linalg.solve(S_safe[None, :, :, :], nu[..., None])[..., 0]
        d2 = np.einsum("mnd,mnd->mn", nu, w)
    d2 = np.where(ok[None, :] & np.isfinite(d2), d2, np.inf)
    return Linearised(kind, nu, H, P, r, S, d2)


def linearised_landmarks(kind: str, nu: np.ndarray, H: np.ndarray, P: np.ndarray, Z: np.ndarray,
                         R: np.ndarray, d2: np.ndarray | None = None) -> Linearised:
    """A linearisation against uncertain landmarks (one FastSLAM particle's map): innovations
    ``nu`` (m, n, d), pose Jacobians ``H`` (n, d, 3), pose covariance ``P`` (3, 3) and each
    landmark's ``Z_j = Hm C_j Hm^T + R`` (n, d, d) (R (d, d) the reading noise), so
    ``S_j = H_j P H_j^T + Z_j``. Landmarks are independent of each other given the pose, so
    only the pose error is shared between readings. ``d2`` (m, n) when the caller has it
    (``inf`` for a landmark to leave out)."""
    S = H @ P @ H.transpose(0, 2, 1) + Z
    if d2 is None:
        with np.errstate(divide="ignore", invalid="ignore"):
            ok = np.all(np.isfinite(S), axis=(1, 2))
            S_safe = np.where(ok[:, None, None], S, np.eye(S.shape[-1]))
            w = np.linalg.solve(S_safe[None, :, :, :], nu[..., None])[..., 0]
            d2 = np.where(ok[None, :], np.einsum("mnd,mnd->mn", nu, w), np.inf)
        d2 = np.where(np.isfinite(d2), d2, np.inf)
    return Linearised(kind, nu, H, P, np.diag(np.asarray(R, dtype=float)).copy(), S, d2, Z)


@lru_cache(maxsize=256)
def gate(prob: float, dof: int) -> float:
    """The chi-square ``prob`` quantile with ``dof`` degrees of freedom (a squared
    Mahalanobis distance at or below it passes)."""
    return chi2_quantile(prob, dof)


def joint_nis(lin: Linearised, pairing: Pairing) -> float:
    """Joint NIS of a pairing [(reading i, beacon row j), ...].

    The innovations of the paired readings are stacked into one vector ``nu`` (k d,) and
    their Jacobians into ``H`` (k d, 3); ``S = H P H^T + R`` over the stack is full, not
    block diagonal: its off-diagonal blocks ``H_a P H_b^T`` are the correlation the one
    shared pose error puts between the readings. ``NIS = nu^T S^-1 nu``.
    """
    if not pairing:
        return 0.0
    rows = np.array([i for i, _ in pairing])
    cols = np.array([j for _, j in pairing])
    nu = lin.nu[rows, cols].reshape(-1)
    H = lin.H[cols].reshape(-1, 3)
    if lin.Z is None:
        D = np.diag(np.tile(lin.r, len(pairing)))
    else:  # block diagonal: each landmark's own noise, independent of the others'
        d = lin.dim
        D = np.zeros((d * len(pairing), d * len(pairing)))
        for k, j in enumerate(cols):
            D[k * d:(k + 1) * d, k * d:(k + 1) * d] = lin.Z[j]
    S = H @ lin.P @ H.T + D
    if not np.all(np.isfinite(S)):
        return math.inf
    try:
        value = float(nu @ np.linalg.solve(S, nu))
    except np.linalg.LinAlgError:
        return math.inf
    return value if math.isfinite(value) else math.inf
