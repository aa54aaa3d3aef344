"""The Kalman update for one run or R runs: S, K, the corrected mean (heading wrapped),
Joseph or plain P; its low-rank (information) form over ``LOW_RANK_ROWS`` rows, the full-R
form for correlated readings, and the NIS."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from beacon_sim.core.angles import wrap as wrap_angle
from beacon_sim.filters.gaussian.measurements.readings import StackedReadings

_I3 = np.eye(3)

#: Readings (rows of a tick's stacked update) above which the Kalman updates take their
#: low-rank forms: with R diagonal (independent readings), ``S = H P H^T + R`` (the EKF's,
#: rank 3) and ``S = dZ^T W dZ + R`` (the UKF's, rank 7) are never formed or solved, and the
#: cost is linear in the rows instead of cubic. At or below it the direct m x m solve runs,
#: as it always did (the same bits; cheaper for a few readings). The two agree to 1e-9.
LOW_RANK_ROWS = 24


def _find_gufunc_solve() -> Callable[..., np.ndarray] | None:
    try:  # the ufunc np.linalg.solve wraps (numpy >= 1.8); absent: the public function
        from numpy.linalg import _umath_linalg
    except ImportError:  # pragma: no cover
        return None
    return getattr(_umath_linalg, "solve", None)


_gufunc_solve = _find_gufunc_solve()


def solve(S: np.ndarray, B: np.ndarray, strict: bool = True) -> np.ndarray:
    """``S^-1 B`` for small symmetric positive-definite S (..., m, m), B (..., m, n).

    The gufunc under ``np.linalg.solve`` (its Python wrapper costs ~10 us on a 4x4 system,
    the gufunc ~3 us). A singular S: with ``strict`` LinAlgError (one run: the filter stops);
    otherwise NaN rows (R runs: one bad run must not stop the others).
    """
    if _gufunc_solve is None:  # pragma: no cover
        return np.linalg.solve(S, B)
    X = _gufunc_solve(S, B)
    if strict and not np.isfinite(X).all():
        return np.linalg.solve(S, B)  # raises LinAlgError for a singular S
    return X


def add_diagonal(S: np.ndarray, r: np.ndarray) -> None:
    """``S += diag(r)`` in place, S (..., m, m) C-contiguous (fresh from a product)."""
    m = S.shape[-1]
    S.reshape(*S.shape[:-2], m * m)[..., :: m + 1] += r


def corrected_mean(mean: np.ndarray, Kt: np.ndarray, nu: np.ndarray) -> np.ndarray:
    """``mean + K nu`` (..., 3) with ``Kt`` = K^T (..., m, 3); heading wrapped."""
    m = mean + (nu[..., None, :] @ Kt)[..., 0, :]
    if m.ndim == 1:
        m[2] = wrap_angle(m[2])  # a numpy scalar: wrap's fast path
    else:
        m[:, 2] = wrap_angle(m[:, 2])
    return m


def symmetrise(P: np.ndarray) -> np.ndarray:
    """``(P + P^T) / 2`` in place (P fresh from the update); returns P."""
    P += P.swapaxes(-1, -2)
    P *= 0.5
    return P


def kalman_update(mean: np.ndarray, P: np.ndarray, H: np.ndarray, nu: np.ndarray, r: np.ndarray,
                  joseph: bool = True, want_nis: bool = False, strict: bool = True
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """The stacked Kalman update of one run or R runs: ``(mean, P, NIS or None)``.

    S = H P H^T + diag(r), K = P H^T S^-1, mean = mean + K nu (heading wrapped),
    P = (I - K H) P (I - K H)^T + K diag(r) K^T (Joseph) or P - K H P, symmetrised;
    NIS = nu^T S^-1 nu. ``strict``: see :func:`solve`. Over :data:`LOW_RANK_ROWS` rows:
    :func:`kalman_update_low_rank`, the same update linear in the rows.
    """
    if H.shape[-2] > LOW_RANK_ROWS:
        return kalman_update_low_rank(mean, P, H, nu, r, joseph, want_nis, strict)
    HP = H @ P                                          # (..., m, 3)
    S = HP @ H.swapaxes(-1, -2)
    add_diagonal(S, r)
    nis = None
    if want_nis:
        X = solve(S, np.concatenate([HP, nu[..., None]], axis=-1), strict)
        Kt = X[..., :3]                                 # K^T = S^-1 H P (P symmetric)
        nis = np.sum(nu * X[..., 3], axis=-1)
    else:
        Kt = solve(S, HP, strict)
    K = Kt.swapaxes(-1, -2)
    mean = corrected_mean(mean, Kt, nu)
    if joseph:
        A = _I3 - K @ H
        P = A @ P @ A.swapaxes(-1, -2) + (K * r[..., None, :]) @ Kt
    else:
        P = P - K @ HP
    return mean, symmetrise(P), nis


def _information(H: np.ndarray, nu: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``G = H^T R^-1 H`` (..., 3, 3) and ``b = H^T R^-1 nu`` (..., 3), R = diag(r): sums over
    the rows, so linear in them."""
    Hr = H / r[..., :, None]
    return H.swapaxes(-1, -2) @ Hr, (nu[..., None, :] @ Hr)[..., 0, :]


def kalman_update_low_rank(mean: np.ndarray, P: np.ndarray, H: np.ndarray, nu: np.ndarray,
                           r: np.ndarray, joseph: bool = True, want_nis: bool = False,
                           strict: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """:func:`kalman_update` without S (m x m): with ``G = H^T R^-1 H``, ``b = H^T R^-1 nu``
    and ``T = (I + P G)^-1 P`` (3 x 3; invertible for P, G positive semi-definite),
    ``S^-1 = R^-1 - R^-1 H T H^T R^-1`` (Woodbury), so ``K = T H^T R^-1``, ``K nu = T b``,
    ``K H = T G``, ``K R K^T = T G T^T`` and ``NIS = nu^T R^-1 nu - b^T T b``."""
    G, b = _information(H, nu, r)
    T = solve(_I3 + P @ G, P, strict)
    mean = corrected_mean(mean, T.swapaxes(-1, -2), b)
    TG = T @ G
    if joseph:
        A = _I3 - TG
        P = A @ P @ A.swapaxes(-1, -2) + TG @ T.swapaxes(-1, -2)
    else:
        P = P - TG @ P
    nis = None
    if want_nis:
        nis = np.sum(nu * nu / r, axis=-1) - np.sum(b * (T @ b[..., None])[..., 0], axis=-1)
    return mean, symmetrise(P), nis


def nis_low_rank(P: np.ndarray, H: np.ndarray, nu: np.ndarray, r: np.ndarray, strict: bool = True
                 ) -> np.ndarray:
    """``nu^T S^-1 nu`` with S = H P H^T + diag(r) never formed (one run or R runs), linear in
    the rows: ``nu^T R^-1 nu - b^T T b`` (:func:`kalman_update_low_rank`)."""
    G, b = _information(H, nu, r)
    T = solve(_I3 + P @ G, P, strict)
    return np.sum(nu * nu / r, axis=-1) - np.sum(b * (T @ b[..., None])[..., 0], axis=-1)


def nis(mean: np.ndarray, P: np.ndarray, st: StackedReadings) -> np.ndarray:
    """Joint NIS ``nu^T S^-1 nu`` (R,) of every reading of the tick against the prior
    ``(mean, P)`` (R runs), as ``evaluation.metrics.nis`` (all kinds, the told noise);
    linear in the rows over :data:`LOW_RANK_ROWS` (see :func:`kalman_update_low_rank`)."""
    H, nu, r = st.linearise(mean)
    if H.shape[-2] > LOW_RANK_ROWS:
        return nis_low_rank(P, H, nu, r, strict=False)
    S = H @ P @ H.swapaxes(-1, -2)
    add_diagonal(S, r)
    return np.sum(nu * solve(S, nu[..., None], strict=False)[..., 0], axis=-1)


def kalman_update_full(mean: np.ndarray, P: np.ndarray, H: np.ndarray, nu: np.ndarray, R: np.ndarray,
                       joseph: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """The Kalman update of one run with a full noise covariance R (m, m) (correlated
    readings): S = H P H^T + R, K = P H^T S^-1, mean + K nu (heading wrapped),
    P = (I - K H) P (I - K H)^T + K R K^T (Joseph) or P - K H P, symmetrised."""
    HP = H @ P
    S = HP @ H.T + R
    Kt = np.linalg.solve(S, HP)                          # K^T = S^-1 H P
    mean = corrected_mean(np.asarray(mean, dtype=float), Kt, nu)
    K = Kt.T
    if joseph:
        A = _I3 - K @ H
        P = A @ P @ A.T + K @ R @ Kt
    else:
        P = P - K @ HP
    return mean, symmetrise(np.array(P))


__all__ = ["LOW_RANK_ROWS", "add_diagonal", "corrected_mean", "kalman_update",
           "kalman_update_full", "kalman_update_low_rank", "nis", "nis_low_rank", "solve",
           "symmetrise"]
