"""The smoothing bound: the posterior Cramer-Rao bound of the whole trajectory.

The filtering bound (``pcrb.py``) bounds the error of an estimate of tick k made from the
readings up to k. A smoother uses every reading of the run, so its bound is the inverse of
the Fisher information of the stacked trajectory ``X = [x_0, x_1, ..., x_T]``, with the
Jacobians along the true path (the same terms as ``pcrb.step_terms``)::

    J = blockdiag(P_0^-1, 0, ...) + sum_k  A_k^T Q_k^-1 A_k  + sum_k  E_k^T I_z,k E_k
    A_k = [.. -F_k (block k - 1)  I (block k) ..],   E_k picks block k

J is block tridiagonal. The diagonal blocks of ``J^-1`` (each tick's bound) come from the
forward recursion of ``pcrb.pcrb`` followed by a Rauch-Tung-Striebel backward pass over the
bound itself (:func:`smoothing_bound`, O(T)); :func:`trajectory_information` builds J
densely for small T, and tests/evaluation/test_smoothing_bound.py holds the two equal. The same
backward pass (``filters/smoothing/rts.py``) turns the filters' moments into the smoothers'.

A known start (P_0 = 0, the simulation's) has no inverse; the forward-backward form needs
none (the smoother gain is 0 there).
"""

from __future__ import annotations

import numpy as np

from beacon_sim.core.scenario import Scenario
from beacon_sim.core.schedule import tick_schedule
from beacon_sim.evaluation.pcrb import information_update, start_cov, step_terms


def forward_terms(scenario: Scenario, truths: np.ndarray, controls: np.ndarray,
                  initial_cov: np.ndarray | None = None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The filtering bound's recursion (``pcrb.pcrb``) with what the backward pass needs.

    truths (R, T + 1, 3), controls (R, T, 2). Returns ``P`` (R, T + 1, 3, 3) (row 0 the
    start), ``P_pred`` (R, T, 3, 3), ``F`` (R, T, 3, 3), and the information ``I_z`` (R, T,
    3, 3) of each tick (zeros where no sensor reads)."""
    truths = np.asarray(truths, dtype=float)
    controls = np.asarray(controls, dtype=float)
    R, T = controls.shape[:2]
    P = np.broadcast_to(np.asarray(start_cov(scenario) if initial_cov is None else initial_cov,
                                   dtype=float), (R, 3, 3)).copy()
    sched = tick_schedule(scenario)
    Ps = np.empty((R, T + 1, 3, 3))
    Pp = np.empty((R, T, 3, 3))
    Fs = np.empty((R, T, 3, 3))
    Iz = np.zeros((R, T, 3, 3))
    Ps[:, 0] = P
    for k in range(1, T + 1):
        F, Q, info = step_terms(scenario, sched, k, truths[:, k - 1], controls[:, k - 1], truths[:, k])
        P = F @ P @ np.swapaxes(F, 1, 2) + Q
        Pp[:, k - 1] = P
        Fs[:, k - 1] = F
        if info is not None:
            Iz[:, k - 1] = info
            P = information_update(P, info)
        Ps[:, k] = P
    return Ps, Pp, Fs, Iz


def smoothing_bound(scenario: Scenario, truths: np.ndarray, controls: np.ndarray,
                    initial_cov: np.ndarray | None = None) -> np.ndarray:
    """The bound on a smoother's error covariance at every tick, shape (R, T, 3, 3) (ticks
    1..T, as ``pcrb.pcrb``) [m^2, m^2, rad^2]: no unbiased estimator of the trajectory from
    all the run's readings does better. truths (R, T + 1, 3), controls (R, T, 2)."""
    P, Pp, F, _ = forward_terms(scenario, truths, controls, initial_cov)
    T = Pp.shape[1]
    out = P.copy()
    for k in range(T - 1, -1, -1):
        PFt = P[:, k] @ np.swapaxes(F[:, k], 1, 2)
        C = PFt @ np.linalg.pinv(Pp[:, k], hermitian=True)  # C = P F^T P_pred^-1
        Ck = C @ (out[:, k + 1] - Pp[:, k]) @ np.swapaxes(C, 1, 2)
        S = P[:, k] + Ck
        out[:, k] = 0.5 * (S + np.swapaxes(S, 1, 2))
    return out[:, 1:]


def trajectory_information(scenario: Scenario, truth: np.ndarray, control: np.ndarray,
                           initial_cov: np.ndarray) -> np.ndarray:
    """The Fisher information J (3 (T + 1), 3 (T + 1)) of one run's stacked trajectory
    (dense: for small T). ``initial_cov`` (3, 3) must be invertible; every tick's Q too."""
    _, _, F, Iz = forward_terms(scenario, truth[None], control[None], initial_cov)
    T = F.shape[1]
    sched = tick_schedule(scenario)
    J = np.zeros((3 * (T + 1), 3 * (T + 1)))
    J[:3, :3] = np.linalg.inv(initial_cov)
    for k in range(1, T + 1):
        _, Q, _ = step_terms(scenario, sched, k, truth[None, k - 1], control[None, k - 1], truth[None, k])
        Qi = np.linalg.inv(Q[0])
        A = np.zeros((3, 3 * (T + 1)))
        A[:, 3 * (k - 1):3 * k] = -F[0, k - 1]
        A[:, 3 * k:3 * k + 3] = np.eye(3)
        J += A.T @ Qi @ A
        J[3 * k:3 * k + 3, 3 * k:3 * k + 3] += Iz[0, k - 1]
    return J


__all__ = ["forward_terms", "smoothing_bound", "trajectory_information"]
