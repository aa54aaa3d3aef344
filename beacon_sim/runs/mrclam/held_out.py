"""Where a MRCLAM run's noise comes from: the data set's other robots (leave one robot out),
their variances inflated to what the held-out robots' EKF runs ask for
(:func:`held_out_inflation`), or the scored run's own ground truth (:func:`calibration_for`)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from beacon_sim.core.metrics import chi2_quantile, nees, pose_errors
from beacon_sim.io.mrclam import MrclamData, MrclamError
from beacon_sim.runs.mrclam.calibration import (
    CALIBRATION_WINDOW_S,
    Calibration,
    calibrate,
    other_runs,
    pooled_calibration,
)
from beacon_sim.runs.mrclam.options import MrclamOptions
from beacon_sim.runs.mrclam.runners import run_calibrated, run_span

#: The quantile of the held-out robots' NEES that :func:`held_out_inflation` puts at the
#: chi-square point of the same probability (3 degrees of freedom).
INFLATION_QUANTILE = 0.99


def held_out_inflation(others: list[MrclamData], window_s: float = CALIBRATION_WINDOW_S
                       ) -> tuple[float, str]:
    """The variance inflation ``kappa >= 1`` the held-out robots ask for, and where it came
    from in words; 1 when fewer than two are held out.

    The errors of this data are not white: odometry drifts and a reading's error (a range
    scaled wrong by the camera, a misplaced landmark) persists while the robot stays near the
    same landmarks, longer than any window the calibration can average over, so noise told
    from the residuals leaves an EKF overconfident in those stretches (heavy tails of its
    NEES). Each held-out robot ``o`` is run through the EKF with the noise pooled from the
    *other* held-out robots (never the scored run, never ``o`` itself); ``kappa`` is the
    ``INFLATION_QUANTILE`` quantile of their NEES, pooled over every step, over the
    chi-square point of that probability (3 dof). Scaling every noise variance (and the
    initial covariance) of a Kalman filter by ``kappa`` leaves its estimates unchanged and
    scales its covariance by ``kappa``, so ``NEES / kappa`` is what the held-out robots would
    have given with the inflated noise: one run per robot, no search."""
    if len(others) < 2:
        return 1.0, "no inflation (fewer than two other robots to check the noise on)"
    values = []
    for o in others:
        rest = [x for x in others if x is not o]
        t_start, t_end = run_span([o], None)
        run = run_calibrated([o], [pooled_calibration(o, rest, window_s)], ["ekf"], t_start, t_end,
                             None, MrclamOptions())
        tr = run.tracks["ekf"]
        if tr.failed or not len(tr.times):
            continue
        truth, ok = o.truth_at(tr.times)
        values.append(nees(pose_errors(tr.means[ok], truth[ok]), tr.covs[ok]))
    if not values:
        return 1.0, "no inflation (no held-out robot could be scored)"
    v = np.concatenate(values)
    kappa = max(1.0, float(np.quantile(v, INFLATION_QUANTILE)) / chi2_quantile(INFLATION_QUANTILE, 3))
    names = ", ".join(f"robot {o.robot}" for o in others)
    return kappa, (f"Gaussian filters' variances x {kappa:.2f}: the {100 * INFLATION_QUANTILE:g} % "
                   f"point of the EKF's NEES on the held-out robots ({names}, each calibrated on "
                   "the others)")


def leave_one_robot_out(data: MrclamData, t_end: float | None = None, inflate: bool = True
                        ) -> Calibration:
    """:func:`pooled_calibration` from the other robots of ``data``'s data set folder, its
    variances inflated by :func:`held_out_inflation` (``inflate``); when the folder holds no
    other robot, the scored run's own calibration, labelled so."""
    others = other_runs(data)
    if not others:
        return replace(calibrate(data, t_end),
                       source="fitted on the scored run's own ground truth: the folder holds no "
                              "other robot to calibrate from")
    cal = pooled_calibration(data, others)
    if not inflate:
        return cal
    kappa, why = held_out_inflation(others)
    return replace(cal, inflation=kappa, stats={**cal.stats, "inflation": kappa},
                   source=f"{cal.source}; {why}")


#: How a MRCLAM run's noise is calibrated: from the data set's other robots, inflated to
#: the held-out robots' consistency (the default); from the other robots, not inflated
#: ("pooled"); or from the scored run's own ground truth (fitted on the answer; labelled).
CALIBRATIONS = ("others", "pooled", "self")


def calibration_for(data: MrclamData, how: str, t_end: float | None = None) -> Calibration:
    """The calibration ``how`` (one of ``CALIBRATIONS``) for ``data``'s run."""
    if how in ("others", "pooled"):
        return leave_one_robot_out(data, t_end, inflate=how == "others")
    if how == "self":
        return replace(calibrate(data, t_end),
                       source="fitted on the scored run's own ground truth (optimistic: not for scoring)")
    raise MrclamError(f"calibration {how!r}: use one of {', '.join(CALIBRATIONS)}")
