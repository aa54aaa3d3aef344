"""The chi-square gate of the EKF and UKF: its default from the sensors' declared outliers,
and the gate on R runs' stacked readings at once."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from beacon_sim.core.metrics import chi2_quantile
from beacon_sim.core.sensor_kinds import sensor_kind
from beacon_sim.filters.base import FilterBase, FilterContext
from beacon_sim.filters.gaussian.measurements.readings import KINDS, StackedReadings

#: Degrees of freedom of one gated group of rows: a beacon's reading or a fix.
READING_DOF = {k: sensor_kind(k).dims for k in KINDS}
#: The gate's chi-square quantile when the scenario tells the filters its readings have
#: outliers and ``gate_chi2`` is not given.
OUTLIER_GATE_QUANTILE = 0.99


def outlier_gate(ctx: FilterContext) -> float:
    """The ``gate_chi2`` an EKF or UKF uses when its parameters do not give one: 0 (no
    gate) unless a sensor the filter is told of (``ctx.sensors``) declares outliers
    (``outlier_rate > 0``); then the chi-square ``OUTLIER_GATE_QUANTILE`` point for the
    most degrees of freedom a gated group of those sensors has (9.21 for range-bearing,
    6.63 for bearings alone). Written into the filter's parameters, so a recording keeps the
    gate it ran with."""
    dofs = [READING_DOF.get(s.kind, 0) for s in ctx.sensors if s.outlier_rate > 0.0]
    dofs = [d for d in dofs if d > 0]
    return chi2_quantile(OUTLIER_GATE_QUANTILE, max(dofs)) if dofs else 0.0


def gate_blocks(st: StackedReadings, nu: np.ndarray, r: np.ndarray, gate: float,
                predicted_cov: Callable[[int, int, int], np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The per-run filters' chi-square gate on R runs at once (one home for the EKF's and the
    UKF's batched gate): each beacon's reading (range and bearing together) or fix whose
    squared Mahalanobis distance ``nu_b^T S_b^-1 nu_b`` exceeds ``gate`` fails, with
    ``S_b = predicted_cov(a, b, width) + R_b``; ``predicted_cov`` gives the block's predicted
    part (R, G, width, width) for the rows ``a:b`` in groups of ``width``. ``nu`` (R, M), ``r``
    (M,) or (R, M); empty slots pass (their innovation is 0).

    Returns ``(keep, rejected)``: ``keep`` (R, M) bool, False on the rows of failed readings,
    and ``rejected`` (R,) the readings that failed, per run."""
    R = nu.shape[0]
    rr = np.broadcast_to(r, nu.shape)
    keep = np.ones(nu.shape, dtype=bool)
    rejected = np.zeros(R, dtype=np.int64)
    for kind, a, b, bxy in st.blocks:
        width = (b - a) if bxy is None else (1 if kind == "bearing" else 2)
        if width <= 0 or b <= a:
            continue
        S = predicted_cov(a, b, width) + rr[:, a:b].reshape(R, -1, width)[..., None] * np.eye(width)
        nb = nu[:, a:b].reshape(R, -1, width)
        d = np.einsum("rgi,rgi->rg", nb, np.linalg.solve(S, nb[..., None])[..., 0])
        bad = d > gate
        rejected += bad.sum(axis=1)
        keep[:, a:b] &= ~np.repeat(bad, width, axis=1)
    return keep, rejected


def gated_rows(st: StackedReadings, cov: np.ndarray, H: np.ndarray, nu: np.ndarray,
               r: np.ndarray, gate: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The per-run EKF's gate on R runs at once (:func:`gate_blocks` with ``S = H P H^T +
    R`` against the predicted belief ``cov`` (R, 3, 3)): a failed reading gets H = 0 and
    innovation 0 (it then changes nothing). ``H`` (R, M, 3), ``nu`` (R, M), ``r`` (M,) or
    (R, M) as :meth:`StackedReadings.linearise` gives them. Returns ``(H, nu, rejected)``,
    ``rejected`` (R,) readings dropped."""
    R = nu.shape[0]

    def linearised(a: int, b: int, width: int) -> np.ndarray:
        Hb = H[:, a:b].reshape(R, -1, width, 3)
        return Hb @ cov[:, None] @ Hb.swapaxes(-1, -2)

    keep, rejected = gate_blocks(st, nu, r, gate, linearised)
    return np.where(keep[..., None], H, 0.0), np.where(keep, nu, 0.0), rejected


def effective_gate(flt: FilterBase) -> float:
    """Set ``flt.params["gate_chi2"]`` to :func:`outlier_gate` when nobody chose a gate
    (the filter's context did not give one, and its class's ``defaults`` keep the built-in
    0: a student's subclass that declares its own gate keeps it), and return the gate."""
    if "gate_chi2" not in flt.ctx.params and float(flt.params.get("gate_chi2", 0.0)) == 0.0:
        flt.params["gate_chi2"] = outlier_gate(flt.ctx)
    return float(flt.params["gate_chi2"])


__all__ = ["OUTLIER_GATE_QUANTILE", "READING_DOF", "effective_gate", "gate_blocks", "gated_rows",
           "outlier_gate"]
