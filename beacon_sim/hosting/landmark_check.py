"""What is wrong with a SLAM filter's map estimate (``landmarks()``, docs/slam.md), in one
message per fault: the same words whether the filter runs in this process (``check
--sandbox none``, the window) or in a child process whose map came back over the pipe
(:mod:`beacon_sim.hosting.wire`, judged in the grader)."""

from __future__ import annotations

from typing import Any

import numpy as np

#: The most landmarks a hosted filter's map may hold (a larger map switches it off).
MAX_LANDMARKS = 4096


def landmark_map_problems(lm: object) -> list[str]:
    """What is wrong with a ``landmarks()`` result (docs/slam.md): a LandmarkMap-like object
    whose ``ids`` are None or M integers, ``means`` (M, 2) and ``covs`` (M, 2, 2) finite, each
    cov symmetric and positive semi-definite. One message per fault; empty when it is right."""
    if lm is None or not all(hasattr(lm, a) for a in ("ids", "means", "covs")):
        return [f"landmarks() returned {type(lm).__name__}, expected a LandmarkMap (ids, means, covs)"]
    out: list[str] = []
    got: Any = lm
    try:
        means = np.asarray(got.means, dtype=np.float64)
        covs = np.asarray(got.covs, dtype=np.float64)
    except (TypeError, ValueError):
        return ["landmarks(): means or covs are not arrays of numbers"]
    if means.ndim != 2 or means.shape[1:] != (2,):
        out.append(f"landmarks(): means of shape {means.shape}, expected (M, 2)")
    if covs.ndim != 3 or covs.shape[1:] != (2, 2):
        out.append(f"landmarks(): covs of shape {covs.shape}, expected (M, 2, 2)")
    m = means.shape[0] if means.ndim == 2 else None
    if m is not None and covs.ndim == 3 and covs.shape[0] != m:
        out.append(f"landmarks(): {m} means but {covs.shape[0]} covs")
    ids = got.ids
    if ids is not None:
        arr = np.asarray(ids)
        if arr.ndim != 1 or not np.issubdtype(arr.dtype, np.integer):
            out.append(f"landmarks(): ids of shape {arr.shape} and type {arr.dtype}, expected (M,) "
                       "integers or None")
        elif m is not None and arr.shape[0] != m:
            out.append(f"landmarks(): {arr.shape[0]} ids but {m} means")
    if not (np.all(np.isfinite(means)) and np.all(np.isfinite(covs))):
        out.append("landmarks(): NaN or infinity in the means or covs")
    elif covs.ndim == 3 and covs.shape[1:] == (2, 2) and len(covs):
        scale = np.maximum(np.max(np.abs(covs), axis=(1, 2)), 1e-12)
        asym = np.max(np.abs(covs - np.swapaxes(covs, 1, 2)), axis=(1, 2))
        bad = np.flatnonzero(asym > 1e-9 * scale)
        if bad.size:
            out.append(f"landmarks(): cov of landmark {int(bad[0])} not symmetric "
                       f"(cov - cov^T up to {float(asym[bad[0]]):.3g})")
        low = np.linalg.eigvalsh(0.5 * (covs + np.swapaxes(covs, 1, 2)))[:, 0]
        neg = np.flatnonzero(low < -1e-9 * scale)
        if neg.size:
            out.append(f"landmarks(): cov of landmark {int(neg[0])} not positive semi-definite "
                       f"(smallest eigenvalue {float(low[neg[0]]):.3g})")
    return out


def landmark_count_problem(m: int) -> str | None:
    """The fault of a map of ``m`` landmarks when it is over :data:`MAX_LANDMARKS`."""
    if m > MAX_LANDMARKS:
        return f"landmarks(): {m} landmarks, at most {MAX_LANDMARKS}"
    return None


__all__ = ["MAX_LANDMARKS", "landmark_count_problem", "landmark_map_problems"]
