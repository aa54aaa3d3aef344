"""Real robot data: robots of a UTIAS MRCLAM data set run through any filter, one robot or
several at once (a single robot is a team of one).

- The noise the filters are told comes from the data (:func:`calibrate`): odometry against
  ground truth and measurement residuals against ground truth, with robust statistics; by
  default from the data set's other robots, never the scored one (:func:`calibration_for`).
- Every filter runs through :class:`~beacon_sim.filters.team_runner.TeamRunner` over the
  robots of :func:`mrclam_team` (:func:`run_mrclam`). One robot: odometry and measurements
  interleaved by time stamp (seed 001 section III.C), the filters predicting with the latest
  command up to each reading's time. Several (issue 18): one common clock, each robot's own
  filter (``independent``) against the team filters that also use the robots' sightings of
  each other.
- :class:`MrclamPlayback` shows a finished run one display tick at a time, for the window.

Reading the files: beacon_sim/io/mrclam.py. Frames and units: metres, radians, world frame
of the data set (Vicon), bearings relative to the heading and wrapped to [-pi, pi).
"""

from __future__ import annotations

import bisect
import math
import time
from collections.abc import Mapping, Sequence, Set
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.clutter import UNKNOWN_ID
from beacon_sim.core.drivers import KeyboardSpec
from beacon_sim.core.keyboard_drive import KeyboardLimits
from beacon_sim.core.measurement_models import relative_bearing
from beacon_sim.core.metrics import chi2_quantile, nees, pose_errors, summary
from beacon_sim.core.motion import MotionNoise
from beacon_sim.core.scenario import InitialBelief, Scenario
from beacon_sim.core.sensors import SensorNoise, SensorSpec
from beacon_sim.core.team import TeamStep
from beacon_sim.core.team_scenario import RobotSensorSpec, TeamRobot, TeamScenario, team_of_one
from beacon_sim.core.types import Beacon, Control, EventRecord, Measurement, Step
from beacon_sim.core.world import World
from beacon_sim.filters.base import Belief, GaussianBelief, LandmarkMap
from beacon_sim.filters.loading import split_label
from beacon_sim.filters.registry import MRCLAM_DEFAULTS, MRCLAM_ROBUST
from beacon_sim.filters.registry import MRCLAM_GATE_CHI2 as MRCLAM_GATE_CHI2  # re-exported
from beacon_sim.filters.runner import HEADLESS_STEP_LIMIT_S, failure_text, guarded_call, validate_estimate
from beacon_sim.filters.team import TEAM_FILTERS
from beacon_sim.filters.team_runner import TeamRunner, validate_team_estimates
from beacon_sim.filters.team_specs import check_team_specs, member_spec, team_filter_name
from beacon_sim.io.mrclam import ROBOT_SUBJECTS, MrclamData, MrclamError
from beacon_sim.runs.headless import ACCURACY_KEYS
from beacon_sim.runs.scene import FilterStatus, Trail

SENSOR_NAME = "camera"
#: Seed 001's UKF figures on MRCLAM (Table II), m^2, m^2, rad^2.
SEED_001_UKF_MSE = (0.0119, 0.0078, 0.0571)
SEED_001_EKF_MSE = (1.7875, 1.889, 7.7997)
#: The correlation time [s] of the errors, about the length of the blind stretches a filter
#: must bridge: odometry is compared with ground truth over windows this long, and readings
#: within one window are treated as sharing their error. Odometry drift and reading errors
#: (landmark survey, range bias, timing) persist over seconds; a white-noise model told the
#: one-step (or 1 s) spread averages them away and is overconfident (docs/replay.md).
CALIBRATION_WINDOW_S = 10.0
#: Sub-step [s] of the ground-truth path when odometry is compared with it.
SUB_S = 0.1
#: Floor of the outlier share the particle and grid filters are told (a mixture with a
#: uniform reading): a reading can always be a misidentified landmark.
MIN_OUTLIER_RATE = 0.01
#: Parameters a MRCLAM run gives the built-in filters unless the caller sets them: the
#: same for every data set and robot. EKF, UKF: a 99.9 % chi-square gate per reading. The
#: particle filter weighs readings with the calibrated outlier mixture; it tracks from a
#: known start in data without kidnaps, so augmented-MCL injection (a recovery mechanism
#: that the long blind stretches and outliers set off, scattering particles over the room:
#: jumps of metres) is off; roughening after resampling keeps the cloud from collapsing
#: below what the shared reading errors allow.
MRCLAM_PARAMS: Mapping[str, Mapping[str, Any]] = MRCLAM_DEFAULTS  # from the filters' records
#: Initial belief: ground truth at the start with these standard deviations [m, m, rad]
#: (local localization with a known start, as seed 001).
INITIAL_STD = (0.05, 0.05, 0.05)


# --------------------------------------------------------------------------------------------
# Noise from the data


def robust_std(x: np.ndarray) -> float:
    """1.4826 x the median absolute deviation from the median: the standard deviation of the
    Gaussian core, not inflated by the heavy tails."""
    x = np.asarray(x, dtype=float)
    if x.size == 0:
        return float("nan")
    return float(1.4826 * np.median(np.abs(x - np.median(x))))


def rms(x: np.ndarray) -> float:
    """Root mean square about zero (a bias counts as error: the filters do not model it)."""
    x = np.asarray(x, dtype=float)
    return float(np.sqrt(np.mean(x * x))) if x.size else float("nan")


def shared_error_factor(err: np.ndarray, groups: np.ndarray) -> float:
    """``sum_g (sum_{i in g} e_i)^2 / sum_i e_i^2``: 1 when the errors within each group are
    independent, the group size when they are identical. The variance a filter must assign
    to each reading so that the readings of a group, treated as independent, carry the
    information they really hold."""
    err = np.asarray(err, dtype=float)
    if err.size == 0:
        return 1.0
    _, inv = np.unique(groups, return_inverse=True)
    total = float(np.sum(err * err))
    if total <= 0:
        return 1.0
    return max(1.0, float(np.sum(np.bincount(inv, weights=err) ** 2)) / total)


def _command_integrals(od: np.ndarray, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Integrals of v and omega from the first odometry row to ``times`` (piecewise constant
    commands, each held until the next row)."""
    t = od[:, 0]
    dt = np.diff(t)
    cum_s = np.concatenate([[0.0], np.cumsum(od[:-1, 1] * dt)])
    cum_a = np.concatenate([[0.0], np.cumsum(od[:-1, 2] * dt)])
    return np.interp(times, t, cum_s), np.interp(times, t, cum_a)


#: The command scales :func:`command_scale` may find; beyond them the data is not odometry.
COMMAND_SCALE_RANGE = (0.5, 1.5)


def command_scale(true: np.ndarray, commanded: np.ndarray) -> float:
    """Least-squares factor ``k`` in ``true = k * commanded`` (displacements or turns over
    the calibration windows), within ``COMMAND_SCALE_RANGE``; 1 without motion. MRCLAM's
    commanded speeds overshoot what the robots drive by 2-8 %, the same on every robot, an
    error a white-noise model cannot remove and that sets the drift of a blind stretch."""
    den = float(np.sum(commanded * commanded))
    if den <= 0:
        return 1.0
    return float(np.clip(np.sum(true * commanded) / den, *COMMAND_SCALE_RANGE))


@dataclass(frozen=True)
class Calibration:
    """Noise settings estimated from one robot's data, and the statistics behind them.

    ``motion`` is per filter step of ``step_dt`` seconds (white noise with the variance of
    the odometry error seen over ``window_s``); ``sensor`` the standard deviations each
    reading is told (RMS of the residuals, inflated for the error readings of one landmark
    share within ``window_s``); ``outlier_rate`` the share of readings the particle and grid
    filters treat as possibly unrelated to the pose.
    """

    motion: MotionNoise
    sensor: SensorNoise
    step_dt: float
    window_s: float
    stats: dict[str, float]
    outlier_rate: float = MIN_OUTLIER_RATE
    #: Where the noise came from, in words (printed beside every MRCLAM result).
    source: str = "fitted on the scored run's own ground truth"
    #: The factor on every variance the Gaussian filters are told (:func:`held_out_inflation`;
    #: :func:`inflated` applies it); the filters that weigh readings with the outlier mixture
    #: are told ``motion`` and ``sensor`` as they are.
    inflation: float = 1.0
    #: What the robot drives per unit commanded, forward and turning (:func:`command_scale`):
    #: the filters predict with the odometry commands times these.
    v_scale: float = 1.0
    omega_scale: float = 1.0


def calibrate(data: MrclamData, t_end: float | None = None,
              window_s: float = CALIBRATION_WINDOW_S) -> Calibration:
    """Estimate the noise the filters are told from the data, where ground truth exists.

    One setting for every data set and robot; nothing here is tuned to one of them.

    Odometry: over consecutive windows of ``window_s`` seconds, the true forward
    displacement and heading change (ground truth, in the robot frame at the window start)
    minus the integrated commands. Their RMS ``s_d`` [m] and ``s_a`` [rad] (tails and bias
    included) become the per-step standard deviations of a white velocity noise with the
    same variance over the window: ``sigma_v = s_d / sqrt(window * step_dt)`` [m/s],
    ``sigma_omega = s_a / sqrt(window * step_dt)`` [rad/s], ``step_dt`` the median odometry
    interval (the filters' step). The error over 10 s is larger than ten 1-s errors would
    give (slip and drift are correlated), so the window is the correlation time, not one step.

    Readings: range and bearing residuals against the ground truth interpolated to the
    reading times. Bearings off by more than pi/2 (a misidentified or flipped reading) are
    counted as outliers and left out; the rest give the RMS (about zero: the median bias is
    error the filters cannot remove). Readings within a window share much of
    their error; the told variance is ``RMS^2 x f`` with ``f`` the shared-error factor
    (:func:`shared_error_factor`, the window as the group), so that a window's
    readings together carry the information they hold. The outlier rate is the share of
    readings beyond 4 told standard deviations (range or bearing), at least
    ``MIN_OUTLIER_RATE``. Robust (MAD) spreads and tail shares are reported in ``stats``.
    """
    od = data.odometry
    t_end = float(od[-1, 0]) if t_end is None else min(float(t_end), float(od[-1, 0]))
    step_dt = float(np.median(np.diff(od[:, 0]))) if len(od) > 1 else 0.01
    step_dt = step_dt if step_dt > 0 else 0.01
    start = max(data.t0, float(data.groundtruth[0, 0]))
    # The path within a window is summed over sub-steps of SUB_S, each projected on its own
    # heading (a chord across a turn is shorter than the arc driven).
    sub = max(1, round(window_s / SUB_S))
    fine = np.arange(start, t_end, window_s / sub)
    n_win = (fine.size - 1) // sub
    stats: dict[str, float] = {}
    if n_win >= 2:
        fine = fine[:n_win * sub + 1]
        pose, ok = data.truth_at(fine)
        s, a = _command_integrals(od, fine)
        d = np.diff(pose[:, :2], axis=0)
        th = pose[:-1, 2]
        fwd = (np.cos(th) * d[:, 0] + np.sin(th) * d[:, 1]).reshape(n_win, sub).sum(axis=1)
        turn = np.diff(np.unwrap(pose[:, 2])).reshape(n_win, sub).sum(axis=1)
        good = ok[:-1].reshape(n_win, sub).all(axis=1) & ok[1:].reshape(n_win, sub).all(axis=1)
        fwd, turn = fwd[good], turn[good]
        c_d, c_a = (s[sub::sub] - s[:-1:sub])[good], (a[sub::sub] - a[:-1:sub])[good]
        v_scale, omega_scale = command_scale(fwd, c_d), command_scale(turn, c_a)
        e_d = fwd - v_scale * c_d
        e_a = wrap(turn - omega_scale * c_a)
        s_d, s_a = rms(e_d), rms(e_a)
        stats.update(v_scale=v_scale, omega_scale=omega_scale, v_scale_weight=float(np.sum(c_d * c_d)),
                     omega_scale_weight=float(np.sum(c_a * c_a)))
        stats.update(windows=int(good.sum()), fwd_err_median_m=float(np.median(e_d)),
                     fwd_err_std_m=s_d, fwd_err_robust_std_m=robust_std(e_d),
                     turn_err_median_rad=float(np.median(e_a)), turn_err_std_rad=s_a,
                     turn_err_robust_std_rad=robust_std(e_a))
    else:
        s_d, s_a = 0.01 * math.sqrt(window_s), 0.02 * math.sqrt(window_s)
        v_scale = omega_scale = 1.0
        stats["windows"] = 0
    scale = math.sqrt(window_s * step_dt)
    motion = MotionNoise(v_std=s_d / scale, omega_std=s_a / scale)

    ms = data.measurements
    ms = ms[ms[:, 0] <= t_end]
    pose, ok = data.truth_at(ms[:, 0])
    ms, pose = ms[ok], pose[ok]
    outlier_rate = MIN_OUTLIER_RATE
    if len(ms) >= 5:
        lxy = np.array([data.landmarks[int(s)] for s in ms[:, 1]])
        dx = lxy[:, 0] - pose[:, 0]
        dy = lxy[:, 1] - pose[:, 1]
        e_r = ms[:, 2] - np.hypot(dx, dy)
        e_b = wrap(ms[:, 3] - relative_bearing(dx, dy, pose[:, 2]))
        flipped = np.abs(e_b) > math.pi / 2
        core_r, core_b = e_r[~flipped], e_b[~flipped]
        groups = np.floor((ms[~flipped, 0] - ms[0, 0]) / window_s)
        f_r = shared_error_factor(core_r, groups)
        f_b = shared_error_factor(core_b, groups)
        s_r = rms(core_r) * math.sqrt(f_r)
        s_b = rms(core_b) * math.sqrt(f_b)
        far = flipped | (np.abs(e_r) > 4 * s_r) | (np.abs(e_b) > 4 * s_b)
        outlier_rate = max(MIN_OUTLIER_RATE, float(np.mean(far)))
        mr, sr = robust_std(core_r), robust_std(core_b)
        stats.update(readings=len(ms), range_err_median_m=float(np.median(e_r)),
                     range_err_rms_m=rms(core_r), range_err_robust_std_m=mr,
                     range_shared_factor=f_r, range_err_std_m=s_r,
                     range_short_tail=float(np.mean(e_r < np.median(e_r) - 3 * mr)),
                     range_long_tail=float(np.mean(e_r > np.median(e_r) + 3 * mr)),
                     bearing_err_median_rad=float(np.median(core_b)),
                     bearing_err_rms_rad=rms(core_b), bearing_err_robust_std_rad=sr,
                     bearing_shared_factor=f_b, bearing_err_std_rad=s_b,
                     bearing_flipped=float(np.mean(flipped)),
                     bearing_tail=float(np.mean(np.abs(core_b) > 3 * sr)),
                     outlier_rate=outlier_rate)
    else:
        s_r, s_b = 0.1, 0.05
        stats["readings"] = len(ms)
    sensor = SensorNoise(bearing_std=max(s_b, 1e-4), range_std=max(s_r, 1e-4))
    return Calibration(motion, sensor, step_dt, window_s, stats, outlier_rate,
                       v_scale=v_scale, omega_scale=omega_scale)


#: The robots of an MRCLAM data set (leave-one-robot-out calibrates from the others).
DATASET_ROBOTS = (1, 2, 3, 4, 5)


def pooled_calibration(data: MrclamData, others: list[MrclamData],
                       window_s: float = CALIBRATION_WINDOW_S) -> Calibration:
    """The noise for ``data``'s run calibrated from other runs only (``others``: other
    robots of the data set, or another data set), never from ``data``'s ground truth.

    Each of ``others`` is calibrated whole (:func:`calibrate`); the error variances are
    pooled, weighted by what each measured them from (odometry windows, readings): the
    window errors ``s_d``, ``s_a`` and the told reading variances (shared-error factor
    included), and the outlier share. The filter step ``step_dt`` is ``data``'s own median
    odometry interval (timing, not ground truth), and the motion noise is rescaled to it as
    in :func:`calibrate`."""
    if not others:
        raise MrclamError(f"{data.folder}: no other run to calibrate robot {data.robot} from")
    cals = [calibrate(o, None, window_s) for o in others]
    od = data.odometry
    step_dt = float(np.median(np.diff(od[:, 0]))) if len(od) > 1 else 0.01
    step_dt = step_dt if step_dt > 0 else 0.01

    def pooled(key: str, weight: str, fallback: str) -> float:
        w = np.array([max(float(c.stats.get(weight, 0)), 0.0) for c in cals])
        v = np.array([float(c.stats.get(key, math.nan)) ** 2 for c in cals])
        ok = np.isfinite(v) & (w > 0)
        if not ok.any():
            return float(np.sqrt(np.mean([getattr(c.sensor, fallback, 0.0) ** 2 for c in cals])))
        return float(np.sqrt(np.sum(w[ok] * v[ok]) / np.sum(w[ok])))

    s_d = pooled("fwd_err_std_m", "windows", "range_std")
    s_a = pooled("turn_err_std_rad", "windows", "bearing_std")
    s_r = pooled("range_err_std_m", "readings", "range_std")
    s_b = pooled("bearing_err_std_rad", "readings", "bearing_std")
    reads = np.array([float(c.stats.get("readings", 0)) for c in cals])
    rates = np.array([c.outlier_rate for c in cals])
    outlier_rate = max(MIN_OUTLIER_RATE, float(np.sum(reads * rates) / reads.sum()) if reads.sum() > 0
                       else MIN_OUTLIER_RATE)
    scale = math.sqrt(window_s * step_dt)
    motion = MotionNoise(v_std=s_d / scale, omega_std=s_a / scale)
    sensor = SensorNoise(bearing_std=max(s_b, 1e-4), range_std=max(s_r, 1e-4))
    names = ", ".join(f"{o.folder.name} robot {o.robot}" for o in others)

    def pooled_scale(key: str) -> float:
        w = np.array([float(c.stats.get(f"{key}_weight", 0.0)) for c in cals])
        k = np.array([float(getattr(c, key)) for c in cals])
        return float(np.sum(w * k) / np.sum(w)) if np.sum(w) > 0 else 1.0

    stats = {"fwd_err_std_m": s_d, "turn_err_std_rad": s_a, "range_err_std_m": s_r,
             "bearing_err_std_rad": s_b, "outlier_rate": outlier_rate,
             "windows": float(sum(c.stats.get("windows", 0) for c in cals)),
             "readings": float(reads.sum())}
    v_scale, omega_scale = pooled_scale("v_scale"), pooled_scale("omega_scale")
    stats.update(v_scale=v_scale, omega_scale=omega_scale)
    return Calibration(motion, sensor, step_dt, window_s, stats, outlier_rate,
                       source=f"calibrated on other runs ({names}), not on the scored run",
                       v_scale=v_scale, omega_scale=omega_scale)


def other_runs(data: MrclamData, robots: tuple[int, ...] = DATASET_ROBOTS) -> list[MrclamData]:
    """The other robots of ``data``'s data set folder that it holds (a folder may hold one)."""
    from beacon_sim.io.mrclam import load_mrclam

    others = []
    for r in robots:
        if r != data.robot and (data.folder / f"Robot{r}_Groundtruth.dat").is_file():
            others.append(load_mrclam(data.folder, r))
    return others


#: The quantile of the held-out robots' NEES that :func:`held_out_inflation` puts at the
#: chi-square point of the same probability (3 degrees of freedom).
INFLATION_QUANTILE = 0.99


def inflated(cal: Calibration) -> Calibration:
    """``cal`` with every noise variance (velocity, turn rate, range, bearing) multiplied by
    its ``inflation``: what the Gaussian filters are told."""
    if cal.inflation == 1.0:
        return cal
    k = math.sqrt(cal.inflation)
    motion = MotionNoise(v_std=cal.motion.v_std * k, omega_std=cal.motion.omega_std * k)
    sensor = SensorNoise(bearing_std=cal.sensor.bearing_std * k, range_std=cal.sensor.range_std * k)
    return replace(cal, motion=motion, sensor=sensor, inflation=1.0)


def told_inflated(spec: str) -> bool:
    """Whether filter ``spec`` (also as ``independent:F``) is told the inflated noise: every
    filter but those whose record weighs readings with the calibrated outlier mixture
    (``MRCLAM_ROBUST``: the particle and grid filters), which answer the heavy tails that way."""
    inner = member_spec(spec)
    return split_label(spec if inner is None else inner)[1] not in MRCLAM_ROBUST


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
        run = run_mrclam(o, ["ekf"], calibration=pooled_calibration(o, rest, window_s))
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


# --------------------------------------------------------------------------------------------
# A scenario-like context for the filters


def mrclam_scenario(data: MrclamData, cal: Calibration, t_start: float, t_end: float,
                    correspondence: str = "known", map_known: bool = True) -> Scenario:
    """A :class:`Scenario` holding what the filters may know: the landmark map, the
    calibrated motion and sensor noise, and the initial belief (ground truth at the start).
    ``correspondence="unknown"`` (``--unknown-ids``, issue 29): the camera's readings carry no
    landmark IDs and the filters associate them with the map themselves. ``map_known=False``
    (``--slam``, issue 29): the surveyed landmarks stay in ``world`` (for scoring) but the
    filters' context holds none of them (``Scenario.filter_world``), as on a simulated SLAM
    scenario without anchors."""
    beacons = tuple(Beacon(int(s), x, y) for s, (x, y) in sorted(data.landmarks.items())
                    if s not in ROBOT_SUBJECTS)
    pts = np.vstack([np.array([[b.x, b.y] for b in beacons]).reshape(-1, 2), data.groundtruth[:, 1:3]])
    lo, hi = pts.min(axis=0) - 1.0, pts.max(axis=0) + 1.0
    world = World(bounds=(float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])), beacons=beacons)
    pose, ok = data.truth_at(np.array([t_start]))
    if not ok[0]:
        raise MrclamError(f"{data.folder}: no ground truth at the start of robot {data.robot}'s "
                          f"odometry (t = {t_start:.3f}); cannot set the initial belief")
    init = (float(pose[0, 0]), float(pose[0, 1]), float(pose[0, 2]))
    sensor = SensorSpec(name=SENSOR_NAME, kind="range_bearing", period=cal.step_dt, noise=cal.sensor,
                        outlier_rate=cal.outlier_rate, correspondence=correspondence)
    return Scenario(
        name=f"mrclam_{data.folder.name}_robot{data.robot}",
        description=f"UTIAS MRCLAM {data.folder.name}, robot {data.robot}",
        source=str(data.folder), dt=cal.step_dt, duration=t_end - t_start, seed=0, world=world,
        initial_pose=init, robot_radius=0.2, motion_noise=cal.motion, sensors=(sensor,),
        driver=KeyboardSpec(), keyboard=KeyboardLimits(), events=(),
        initial_belief=InitialBelief(mean=init, std=INITIAL_STD),
        model_motion_noise=cal.motion, model_sensors=(sensor,),
        default_filters=("ekf", "ukf", "dead_reckoning"),
        filter_params={k: dict(v) for k, v in MRCLAM_PARAMS.items()},
        map_known=map_known,
    )


# --------------------------------------------------------------------------------------------
# The robots of a run: a team (a single robot is a team of one)

#: The robot-sighting "sensor" of a team run: a robot's camera reading another robot's
#: barcode, told the same noise as that robot's landmark readings (the same camera).
SIGHTING_SENSOR = "camera_robots"
#: The filters of a team run unless others are named: every robot's own EKF (landmarks
#: only, the baseline) against the team filters that also use the sightings.
TEAM_MRCLAM_FILTERS = ("independent", "centralised", "decentralised", "ci")
#: The common clock of a team run [s]: every robot moves by the exact integral of its
#: piecewise-constant commands over a tick, and the readings stamped inside a tick update at
#: its end (a time error below the tick: 4 mm at MRCLAM's 0.08 m/s for 0.05 s).
TEAM_DT = 0.05
#: The true pose a step of a data set run carries: not known to the run (filters never
#: read it; the ground truth is looked up when scoring).
_UNKNOWN_POSE = np.full(3, np.nan)
_NO_READINGS: tuple[Measurement, ...] = ()


def _union_world(worlds: Sequence[World]) -> World:
    """One world holding every robot's: the landmarks, and bounds around all their paths."""
    lo = np.min([w.bounds[:2] for w in worlds], axis=0)
    hi = np.max([w.bounds[2:] for w in worlds], axis=0)
    return replace(worlds[0], bounds=(float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])))


def mrclam_team(data: Sequence[MrclamData], cals: Sequence[Calibration], t_start: float,
                t_end: float, dt: float = TEAM_DT, correspondence: str = "known",
                map_known: bool = True) -> TeamScenario:
    """The robots of a run as a :class:`TeamScenario`: each robot's own scenario
    (:func:`mrclam_scenario`, its calibrated noise and ground-truth start). One robot is a
    team of one (``solo``: exactly the single-robot scenario). Several robots (IDs = their
    subject numbers, what the sightings report) share a world around all their paths and a
    clock of ``dt`` [s]; each has the sighting sensor, and the team filters the EKF's gate.
    ``correspondence``, ``map_known``: the landmark camera's and the map's (:func:`mrclam_scenario`)."""
    scenarios = [mrclam_scenario(d, c, t_start, t_end, correspondence, map_known)
                 for d, c in zip(data, cals, strict=True)]
    if len(scenarios) == 1:
        return team_of_one(scenarios[0])
    robots = []
    for d, cal, sc in zip(data, cals, scenarios, strict=True):
        seen = RobotSensorSpec(SIGHTING_SENSOR, "robot_range_bearing", period=dt, noise=cal.sensor)
        robots.append(TeamRobot(f"robot{d.robot}", d.robot, sc, (seen,), (seen,)))
    first = scenarios[0]
    gates = {n: {"gate_chi2": MRCLAM_GATE_CHI2} for n in TEAM_FILTERS if n != "independent"}
    return TeamScenario(
        name=f"mrclam_{data[0].folder.name}_team", source=str(data[0].folder),
        description=f"UTIAS MRCLAM {data[0].folder.name}, robots "
                    f"{', '.join(str(d.robot) for d in data)}",
        dt=dt, duration=t_end - t_start, seed=0, world=_union_world([s.world for s in scenarios]),
        keyboard=first.keyboard, robots=tuple(robots), default_filters=TEAM_MRCLAM_FILTERS,
        filter_params=gates)


# --------------------------------------------------------------------------------------------
# Running filters on the data


def nees_or_inf(errors: np.ndarray, covs: np.ndarray) -> np.ndarray:
    """Per step NEES ``e^T P^-1 e`` (T,), infinite at a step whose covariance is singular (a
    filter that claims no uncertainty in some direction: e.g. every particle on one pose),
    as ``summary`` scores the ANEES of such a track."""
    try:
        return nees(errors, covs)
    except np.linalg.LinAlgError:
        out = np.full(len(errors), math.inf)
        good = np.linalg.det(covs) != 0
        if good.any():
            out[good] = nees(errors[good], covs[good])
        return out


@dataclass
class MrclamTrack:
    """One filter's estimates of one robot at the recorded times: every odometry row and
    every update of a single-robot run, every tick of a team run."""

    name: str
    filter: Any  # the filter object (a team filter's for its robots), None: never built
    times: np.ndarray  # (T,) [s], data set clock
    means: np.ndarray  # (T, 3) [m, m, rad], world frame
    covs: np.ndarray  # (T, 3, 3)
    us_per_step: float = 0.0  # [us] per step fed (predict, update, estimate)
    joint: bool = False  # a team filter's (one filter over every robot), not the robot's own
    failed: str | None = None
    failed_time_s: float | None = None  # [s] from the start of the run
    traceback: str = ""


@dataclass
class MrclamRun:
    """The result of :func:`run_mrclam` over ``robots`` (in team order). A single-robot
    run is a team of one: ``data``, ``calibration``, ``scenario`` and ``tracks`` are its
    robot's (robot 0 of a team)."""

    robots: list[MrclamData]
    team: TeamScenario
    calibrations: list[Calibration]
    robot_tracks: list[dict[str, MrclamTrack]]  # per robot: filter name -> track
    t_start: float
    t_end: float
    updates: int
    readings: int
    wall_s: float
    failed: dict[str, str] = field(default_factory=dict)  # name -> why and when (no score)
    #: ``--unknown-ids``: the readings reached the filters without IDs; per filter reporting
    #: ``associations()``, how they were associated (the barcodes only score them).
    unknown_ids: bool = False
    associations: dict[str, AssociationCount] = field(default_factory=dict)
    #: ``--slam``: the SLAM filters were not given the landmark map; per filter name, whether
    #: it was given the surveyed map (True for every filter without ``--slam``).
    slam: bool = False
    map_given: dict[str, bool] = field(default_factory=dict)
    #: ``record_maps``: each SLAM filter's map after each update (the window draws it).
    map_history: dict[str, MapHistory] = field(default_factory=dict)

    @property
    def data(self) -> MrclamData:
        return self.robots[0]

    @property
    def calibration(self) -> Calibration:
        return self.calibrations[0]

    @property
    def scenario(self) -> Scenario:
        return self.team.robots[0].scenario

    @property
    def tracks(self) -> dict[str, MrclamTrack]:
        return self.robot_tracks[0]

    def evaluate(self, robot: int = 0) -> dict[str, dict[str, Any]]:
        """Per filter, robot ``robot``'s (index in team order) per-axis MSE, RMSE and ANEES
        where its ground truth exists, the share of steps whose NEES is above the chi-square
        99 % point, the largest jump of the estimate [m]; no score for a failed filter."""
        data = self.robots[robot]
        out: dict[str, dict[str, Any]] = {}
        for name, tr in self.robot_tracks[robot].items():
            row: dict[str, Any] = {}
            if tr.failed:  # no score for a filter that failed
                row.update(dict.fromkeys(ACCURACY_KEYS))
            elif len(tr.means):
                times = tr.times
                truth, ok = data.truth_at(times)
                if ok.any():
                    means, covs = tr.means[ok], tr.covs[ok]
                    row.update(summary(means, covs, truth[ok]))
                    v = nees_or_inf(pose_errors(means, truth[ok]), covs)
                    row["nees_above_99"] = float(np.mean(v > chi2_quantile(0.99, 3)))
                    steps = np.hypot(*np.diff(tr.means[:, :2], axis=0).T)
                    row["largest_jump_m"] = float(steps.max()) if steps.size else 0.0
                row["evaluated_s"] = float(np.sum(np.diff(times)[ok[1:]])) if len(times) > 1 else 0.0
            row["us_per_step"] = tr.us_per_step
            for attr in ("rejected", "n_rejected", "gated"):
                value = getattr(tr.filter, attr, None)
                if isinstance(value, int | np.integer):
                    row["rejected_readings"] = int(value)
            if tr.failed:
                row["failed"] = tr.failed
                row["failed_time_s"] = tr.failed_time_s
            out[name] = row
        return out

    def as_json(self) -> dict[str, Any]:
        """A single robot's run: its noise, calibration and one row per filter. A team's:
        per working filter one row per robot (subject number as a string), the failed ones
        apart. ``dataset`` is the data set folder's name, never its path (a JSON file is shared)."""
        if not self.team.solo:
            rows = [self.evaluate(i) for i in range(len(self.robots))]
            first = self.robot_tracks[0]
            return {
                "dataset": self.data.folder.name, "robots": [d.robot for d in self.robots],
                "duration_s": self.t_end - self.t_start,
                "landmark_readings": {d.robot: len(d.measurements) for d in self.robots},
                "robot_sightings": {d.robot: len(d.sightings) for d in self.robots},
                "calibration_source": {d.robot: c.source for d, c in zip(self.robots, self.calibrations,
                                                                         strict=True)},
                "filters": {n: {str(d.robot): r[n] for d, r in zip(self.robots, rows, strict=True)}
                            for n in first if n not in self.failed},
                "us_per_step": {n: (first[n].us_per_step if first[n].joint else
                                    sum(t[n].us_per_step for t in self.robot_tracks))
                                for n in first if n not in self.failed},
                "wall_s": self.wall_s, "failed": self.failed,
            }
        cal = self.calibration
        return {
            "dataset": self.data.folder.name, "robot": self.data.robot,
            "t_start": self.t_start, "duration_s": self.t_end - self.t_start,
            "odometry_rows": int(np.sum((self.data.odometry[:, 0] >= self.t_start)
                                        & (self.data.odometry[:, 0] <= self.t_end))),
            "updates": self.updates, "readings": self.readings, "dropped": self.data.dropped,
            "noise": {"v_std": cal.motion.v_std, "omega_std": cal.motion.omega_std,
                      "range_std": cal.sensor.range_std, "bearing_std": cal.sensor.bearing_std,
                      "step_dt": cal.step_dt, "gaussian_inflation": cal.inflation,
                      "v_scale": cal.v_scale, "omega_scale": cal.omega_scale},
            "calibration": cal.stats,
            "calibration_source": cal.source,
            "filters": self.evaluate(),
            "wall_s": self.wall_s,
            "unknown_ids": self.unknown_ids,
            "slam": self.slam,
            "map_given": {n: self.map_given.get(n, True) for n in self.tracks},
            "associations": {n: a.as_json() for n, a in self.associations.items()
                             if n not in self.failed},
        }

def _feed(runners: Sequence[TeamRunner], tick: int, time_s: float, dt: float,
          controls: Sequence[Control], readings: Sequence[tuple[Measurement, ...]],
          sightings: Sequence[tuple[Measurement, ...]] | None = None) -> None:
    """One step of ``dt`` [s] ending at ``time_s`` (from the start) for every robot."""
    steps = tuple(Step(tick, time_s, dt, _UNKNOWN_POSE, u, r)
                  for u, r in zip(controls, readings, strict=True))
    step = TeamStep(tick, time_s, dt, steps, tuple(sightings or (_NO_READINGS,) * len(steps)))
    for runner in runners:
        runner.feed(step)


@dataclass
class AssociationCount:
    """One filter's associations of the readings it was given without IDs (``--unknown-ids``),
    scored against the barcodes the data set recorded (which the filter never saw).

    ``correct``: given the landmark whose barcode the camera read; ``false``: given another
    landmark; ``missed``: given none (dropped as clutter). ``readings`` = their sum: the rows
    of the updates after which the filter reported ``associations()`` for the camera."""

    readings: int = 0
    correct: int = 0
    false: int = 0
    missed: int = 0

    @property
    def fraction_correct(self) -> float:
        """Share of the scored readings given the right landmark (nan with none)."""
        return self.correct / self.readings if self.readings else math.nan

    def add(self, given: Sequence[int | None], truth: np.ndarray) -> None:
        """Count one reading's rows: ``given`` per row (landmark ID or None), ``truth`` the barcodes."""
        for g, t in zip(given, truth.tolist(), strict=True):
            self.readings += 1
            if g is None:
                self.missed += 1
            elif int(g) == int(t):
                self.correct += 1
            else:
                self.false += 1

    def as_json(self) -> dict[str, float]:
        return {"readings": self.readings, "correct": self.correct, "false": self.false,
                "missed": self.missed, "fraction_correct": self.fraction_correct}


#: Seed of the shuffle of each time stamp's rows when their IDs are hidden (the file's order
#: must not hint at the landmark); fixed, so a run is the same bit for bit.
UNKNOWN_IDS_SHUFFLE_SEED = 29


def _score_associations(runners: Sequence[TeamRunner], truth: np.ndarray, time_s: float,
                        scores: dict[str, AssociationCount]) -> None:
    """After an update with hidden IDs: each working filter's ``associations()`` for the camera
    against the barcodes ``truth`` of the rows it was given (in the order given). A filter
    without the method is not scored; one whose method raises is switched off."""
    for runner in runners:
        for name, track in runner.members[0].tracks.items():
            report = getattr(track.filter, "associations", None)
            if track.failed or report is None:
                continue
            try:
                given = report()
            except Exception as exc:  # the filter's own method: switched off, never scored
                runner.fail(name, f"associations() raised {type(exc).__name__}: {exc}"[:200], "", time_s)
                continue
            rows = given.get(SENSOR_NAME) if isinstance(given, dict) else None
            if rows is not None and len(rows) == len(truth):
                scores.setdefault(name, AssociationCount()).add(tuple(rows), truth)


@dataclass
class MapHistory:
    """One SLAM filter's map after each update of a run (``--slam`` shown in the window):
    the data set times [s] and the :class:`~beacon_sim.filters.base.LandmarkMap` then."""

    times: list[float] = field(default_factory=list)
    maps: list[LandmarkMap] = field(default_factory=list)

    def at(self, t: float) -> LandmarkMap | None:
        """The latest map at or before time ``t`` [s]; None before the first."""
        i = bisect.bisect_right(self.times, t) - 1
        return self.maps[i] if i >= 0 else None


def _record_maps(runners: Sequence[TeamRunner], t: float, t_start: float,
                 maps: dict[str, MapHistory]) -> None:
    """Every working single-robot filter's ``landmarks()`` at data set time ``t`` [s] into
    ``maps``; a filter whose method raises is switched off (it would not be drawn either)."""
    for runner in runners:
        for name, track in runner.members[0].tracks.items():
            report = getattr(track.filter, "landmarks", None)
            if track.failed or not callable(report):
                continue
            try:
                lm = report()
                snap = LandmarkMap(None if lm.ids is None else np.array(lm.ids).copy(),
                                   np.array(lm.means, dtype=float).reshape(-1, 2),
                                   np.array(lm.covs, dtype=float).reshape(-1, 2, 2))
            except Exception as exc:  # the filter's own method: switched off
                runner.fail(name, f"landmarks() raised {type(exc).__name__}: {exc}"[:200], "", t - t_start)
                continue
            hist = maps.setdefault(name, MapHistory())
            hist.times.append(float(t))
            hist.maps.append(snap)


def _feed_by_time_stamps(runners: Sequence[TeamRunner], data: MrclamData, cal: Calibration,
                         t_start: float, t_end: float,
                         scores: dict[str, AssociationCount] | None = None,
                         maps: dict[str, MapHistory] | None = None
                         ) -> tuple[np.ndarray, np.ndarray, int, int]:
    """One robot's odometry and readings interleaved by time stamp (seed 001 section III.C):
    predict with the latest command (times ``cal``'s command scales) up to each reading's time
    stamp, in steps of at most 1.5 median odometry intervals (long gaps are split), update
    with all readings of that stamp, go on.

    Returns the time of every record (the start, every odometry row and every update), the
    runner tick whose estimate it shows (0: the initial belief), the updates and readings.

    ``scores`` given (``--unknown-ids``): every reading reaches the filters with its IDs
    ``UNKNOWN_ID`` and its rows shuffled, and after each update the filters' associations are
    counted into ``scores`` against the barcodes (:func:`_score_associations`).

    ``maps`` given (``--slam`` in the window): after each update every working SLAM filter's
    ``landmarks()`` is kept in ``maps`` (:func:`_record_maps`), for the playback to draw."""
    od = data.odometry
    shuffle = np.random.default_rng(UNKNOWN_IDS_SHUFFLE_SEED)
    ms = data.measurements
    ms = ms[(ms[:, 0] > t_start) & (ms[:, 0] <= t_end)]
    group_t, group_start = np.unique(ms[:, 0], return_index=True)
    group_end = np.append(group_start[1:], len(ms))
    od_sel = od[(od[:, 0] > t_start) & (od[:, 0] <= t_end)]
    first = int(np.searchsorted(od[:, 0], t_start, side="right")) - 1
    kv, kw = cal.v_scale, cal.omega_scale
    u = Control(float(od[first, 1]) * kv, float(od[first, 2]) * kw)
    max_step = 1.5 * cal.step_dt
    times, ticks = [t_start], [0]
    t, tick = t_start, 0
    i_od = i_me = 0
    n_od, n_me = len(od_sel), len(group_t)
    while i_od < n_od or i_me < n_me:
        t_od = od_sel[i_od, 0] if i_od < n_od else math.inf
        t_me = group_t[i_me] if i_me < n_me else math.inf
        t_next = min(t_od, t_me)
        reading: tuple[Measurement, ...] = _NO_READINGS
        if t_me <= t_od:
            a, b = group_start[i_me], group_end[i_me]
            rows = ms[a:b]
            if scores is not None:
                rows = rows[shuffle.permutation(len(rows))]
                ids = np.full(len(rows), UNKNOWN_ID, dtype=int)
            else:
                ids = rows[:, 1].astype(int)
            reading = (Measurement(SENSOR_NAME, "range_bearing", rows[:, 2:4].copy(), ids),)
        dt = t_next - t
        if dt > 0 or reading:  # a repeated odometry stamp only changes the command
            n = max(1, math.ceil(dt / max_step - 1e-9))
            h = dt / n
            for j in range(n):
                tick += 1
                _feed(runners, tick, t + (j + 1) * h - t_start, h, (u,),
                      (reading if j == n - 1 else _NO_READINGS,))
            if reading and scores is not None:
                _score_associations(runners, rows[:, 1].astype(int), t_next - t_start, scores)
            if reading and maps is not None:
                _record_maps(runners, t_next, t_start, maps)
        t = t_next
        if reading:
            i_me += 1
        else:
            u = Control(float(od_sel[i_od, 1]) * kv, float(od_sel[i_od, 2]) * kw)
            i_od += 1
        times.append(t)
        ticks.append(tick)
    return np.array(times), np.array(ticks, dtype=np.int64), n_me, len(ms)


def _per_tick(rows: np.ndarray, sensor: str, kind: str, t_start: float, t_last: float, dt: float,
              n_ticks: int) -> dict[int, tuple[Measurement, ...]]:
    """Readings stamped in (t_k, t_k+1] as tick k's, one per subject and tick (the first)."""
    rows = rows[(rows[:, 0] > t_start) & (rows[:, 0] <= t_last)]
    k = np.clip(np.ceil((rows[:, 0] - t_start) / dt).astype(int) - 1, 0, n_ticks - 1)
    out: dict[int, tuple[Measurement, ...]] = {}
    for kk in np.unique(k):
        sel = rows[k == kk]
        _, first = np.unique(sel[:, 1], return_index=True)
        sel = sel[np.sort(first)]
        out[int(kk)] = (Measurement(sensor, kind, sel[:, 2:4].copy(), sel[:, 1].astype(np.int64)),)
    return out


def _feed_on_a_clock(runners: Sequence[TeamRunner], data: Sequence[MrclamData],
                     cals: Sequence[Calibration], t_start: float, t_end: float,
                     dt: float) -> tuple[np.ndarray, np.ndarray, int, int]:
    """Every robot on one clock of ``dt`` [s] from ``t_start``: each tick a robot moves by
    the exact integral of its piecewise-constant odometry commands over the tick
    (v = ds/dt, omega = da/dt, times its calibration's command scales); the landmark readings
    and sightings stamped inside the tick update at its end. Returns the tick times, the
    ticks, the ticks with a landmark reading, and the landmark readings used."""
    n_ticks = int((t_end - t_start) // dt)
    times = t_start + dt * np.arange(n_ticks + 1)
    controls = []
    for d, cal in zip(data, cals, strict=True):
        s, a = _command_integrals(d.odometry, times)
        controls.append([Control(float(v), float(w)) for v, w in
                         zip(np.diff(s) / dt * cal.v_scale, np.diff(a) / dt * cal.omega_scale, strict=True)])
    landmarks = [_per_tick(d.measurements, SENSOR_NAME, "range_bearing", t_start, times[-1], dt, n_ticks)
                 for d in data]
    seen = [_per_tick(d.sightings, SIGHTING_SENSOR, "robot_range_bearing", t_start, times[-1], dt,
                      n_ticks) for d in data]
    for k in range(n_ticks):
        _feed(runners, k + 1, float(times[k + 1] - t_start), dt, [c[k] for c in controls],
              [lm.get(k, _NO_READINGS) for lm in landmarks], [s.get(k, _NO_READINGS) for s in seen])
    updates = len(set().union(*landmarks))
    used = sum(len(m) for lm in landmarks for ms in lm.values() for m in ms)
    return times, np.arange(n_ticks + 1), updates, used


def _start_estimates(runner: TeamRunner) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Every working filter's estimate of every robot before the first step (the initial
    belief): name -> (means (N, 3), covs (N, 3, 3)); a filter whose estimate is unusable is
    switched off."""
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for name in runner.names:
        if runner.failed(name):
            continue
        member = runner.is_member(name)
        objs = ([runner.members[i].tracks[name].filter for i in range(runner.n_robots)] if member
                else [runner.joint.tracks[name].filter])
        calls = [getattr(obj, "estimate" if member else "estimates") for obj in objs]
        got = []
        for call in calls:
            raw, why, tb = guarded_call(call, HEADLESS_STEP_LIMIT_S)
            est = (f"estimate(): {why}" if why is not None else validate_estimate(raw) if member
                   else validate_team_estimates(raw, runner.n_robots))
            if isinstance(est, str):
                runner.fail(name, est, tb, 0.0)
                break
            got.append(est)
        else:
            out[name] = ((np.array([g[0] for g in got]), np.array([g[1] for g in got]))
                         if member else got[0])
    return out


def _robot_tracks(runner: TeamRunner, start: dict[str, tuple[np.ndarray, np.ndarray]],
                  times: np.ndarray, ticks: np.ndarray) -> list[dict[str, MrclamTrack]]:
    """Each robot's track of each filter at the recorded ``times`` (the estimate after runner
    tick ``ticks``; a filter that failed keeps the records before it failed)."""
    out: list[dict[str, MrclamTrack]] = [{} for _ in range(runner.n_robots)]
    for name in runner.names:
        _, means, covs = runner.series(name)
        if name in start:
            means = np.concatenate([start[name][0][None], means])
            covs = np.concatenate([start[name][1][None], covs])
        keep = ticks < len(means)
        for i in range(runner.n_robots):
            tr = runner.track(name, i)
            failed = runner.failed(name)
            out[i][name] = MrclamTrack(
                name, tr.filter, times[keep], means[ticks[keep], i], covs[ticks[keep], i],
                us_per_step=tr.us_per_step, joint=not runner.is_member(name), failed=failed,
                failed_time_s=(tr.failed_time_s if tr.failed_time_s is not None else 0.0) if failed else None,
                traceback=tr.traceback)
    return out


#: The filters of ``--slam`` unless others are named: EKF-SLAM and FastSLAM 2.0 (no map),
#: and the EKF given the surveyed map, for comparison.
SLAM_MRCLAM_FILTERS = ("ekf_slam", "fastslam", "ekf")


def map_withheld(spec: str) -> bool:
    """Whether ``--slam`` withholds the map from filter ``spec``: a SLAM filter (its class has
    ``landmarks()``, docs/slam.md) maps the landmarks itself; any other filter keeps the
    surveyed map (it could not run without it) and is the known-map reference."""
    from beacon_sim.filters.loading import load_filter_class

    return callable(getattr(load_filter_class(spec), "landmarks", None))


def run_mrclam(data: MrclamData | Sequence[MrclamData], filters: list[str] | None = None,
               duration: float | None = None, params: dict[str, dict[str, Any]] | None = None,
               calibration: Calibration | str | None = "others", dt: float | None = None,
               unknown_ids: bool = False, slam: bool = False, record_maps: bool = False) -> MrclamRun:
    """Run filters over one robot's data, or over several robots of a data set at once.

    Every filter runs through :class:`~beacon_sim.filters.team_runner.TeamRunner` (one
    robot is a team of one, :func:`mrclam_team`), starting at the ground truth of the
    first common odometry time (``INITIAL_STD``). One robot (``dt`` None): its odometry and
    readings interleaved by time stamp (:func:`_feed_by_time_stamps`); single-robot filter
    specs. Several robots (or ``dt`` given): one clock of ``dt`` (default ``TEAM_DT``) [s]
    (:func:`_feed_on_a_clock`); team filter specs (``independent:F``, ``centralised``, ...;
    their sightings need the data loaded with ``robot_sightings=True``).

    ``calibration``: ``"others"`` (each robot's noise from the other robots of its folder,
    the default; the Gaussian filters' inflation, measured on the single-robot EKF, only
    for one robot: a team run is told the ``"pooled"`` noise), ``"pooled"``, ``"self"``
    (fitted on its own ground truth, labelled), or a :class:`Calibration` for every robot.
    Built-in filters get ``MRCLAM_PARAMS`` (the EKF's
    and UKF's chi-square gate, the particle filter's settings: the robots' scenario
    ``[filters.*]``) unless ``params`` set them; the particle and grid filters weigh
    readings with the calibrated outlier mixture (docs/replay.md).

    ``unknown_ids`` (one robot, interleaved by time stamp; issue 29): the camera declares
    ``correspondence = "unknown"`` and every reading reaches the filters without its barcode
    (``UNKNOWN_ID``, rows shuffled), so they associate; the barcodes only score that
    (``MrclamRun.associations``). The noise is calibrated as without it (from ground truth and
    the barcodes of the other robots, or the run's own for ``"self"``).

    ``slam`` (one robot, interleaved by time stamp; issue 29): every SLAM filter (a filter
    with ``landmarks()``) is built on a scenario whose map is withheld (``map_known`` False, no
    anchors: it maps the 15 landmarks itself from the known start); every other filter keeps
    the surveyed map, as the reference (:func:`map_withheld`). Default filters
    ``SLAM_MRCLAM_FILTERS``. With ``unknown_ids`` too, the readings also come without barcodes.
    ``record_maps`` (one robot): keep every SLAM filter's map after each update
    (``MrclamRun.map_history``), for the window.
    """
    from beacon_sim.filters.loading import check_param_names, filter_names

    robots = [data] if isinstance(data, MrclamData) else list(data)
    if not robots:
        raise MrclamError("run_mrclam: no robot to run")
    t_start = max(d.t0 for d in robots)
    t_end = min(float(d.odometry[-1, 0]) for d in robots)
    if duration is not None:
        t_end = min(t_end, t_start + duration)
    if unknown_ids and (len(robots) > 1 or dt is not None):
        raise MrclamError("--unknown-ids runs one robot by its time stamps: use --robot N, not --team")
    if slam and (len(robots) > 1 or dt is not None):
        raise MrclamError("--slam runs one robot by its time stamps: use --robot N, not --team "
                          "(the team filters are localization filters; none maps landmarks)")
    correspondence = "unknown" if unknown_ids else "known"
    how = "self" if calibration is None else calibration
    if how == "others" and len(robots) > 1:
        how = "pooled"  # the inflation is the single-robot EKF's (interleaved by time stamp)
    cals = [how if isinstance(how, Calibration) else calibration_for(d, how, t_end) for d in robots]
    dt_team = TEAM_DT if dt is None else dt
    team = mrclam_team(robots, [inflated(c) for c in cals], t_start, t_end, dt_team, correspondence)
    specs = list((SLAM_MRCLAM_FILTERS if slam else team.default_filters) if filters is None else filters)
    if team.solo:
        check_param_names(params, specs)
    else:
        check_team_specs(specs, team, params)
    # the Gaussian filters told the inflated noise, the robust ones the pooled noise; with
    # --slam the SLAM filters get no map, the others keep it
    withheld = {s: slam and map_withheld(s) for s in specs}
    keys = [(inf, blind) for inf in (True, False) for blind in (False, True)]
    groups = [[s for s in specs if told_inflated(s) == inf and withheld[s] == blind] for inf, blind in keys]
    teams = [mrclam_team(robots, [inflated(c) for c in cals] if inf else cals, t_start, t_end, dt_team,
                         correspondence, map_known=not blind) if group else team
             for (inf, blind), group in zip(keys, groups, strict=True)]
    runners = [TeamRunner(tm, group, 0, params, step_limit_s=HEADLESS_STEP_LIMIT_S)
               for tm, group in zip(teams, groups, strict=True) if group]
    names = filter_names(specs) if team.solo else [team_filter_name(s) for s in specs]
    if sorted(n for r in runners for n in r.names) != sorted(names):  # a name primed across groups
        if slam and len(set(withheld.values())) > 1:
            raise MrclamError("--slam: give SLAM filters and map-given filters different names "
                              f"(got {', '.join(specs)})")
        blind_team = mrclam_team(robots, [inflated(c) for c in cals], t_start, t_end, dt_team,
                                 correspondence, map_known=False) if any(withheld.values()) else team
        runners = [TeamRunner(blind_team, specs, 0, params, step_limit_s=HEADLESS_STEP_LIMIT_S)]
    starts = [_start_estimates(r) for r in runners]
    t0 = time.perf_counter()
    scores: dict[str, AssociationCount] | None = {} if unknown_ids else None
    maps: dict[str, MapHistory] | None = {} if record_maps else None
    if team.solo and dt is None:
        times, ticks, updates, readings = _feed_by_time_stamps(runners, robots[0], cals[0], t_start,
                                                               t_end, scores, maps)
    else:
        times, ticks, updates, readings = _feed_on_a_clock(runners, robots, cals, t_start, t_end,
                                                           dt_team)
    wall = time.perf_counter() - t0
    failed = {}
    tracks: list[dict[str, MrclamTrack]] = [{} for _ in robots]
    for runner, start in zip(runners, starts, strict=True):
        for name in runner.names:
            if runner.failed(name):
                failed[name] = failure_text(runner.track(name)) or str(runner.failed(name))
        for mine, theirs in zip(tracks, _robot_tracks(runner, start, times, ticks), strict=True):
            mine.update(theirs)
    tracks = [{n: t[n] for n in names} for t in tracks]  # in the order the filters were named
    given = {n: not withheld[s] for n, s in zip(names, specs, strict=True)}
    return MrclamRun(robots, team, cals, tracks, t_start, t_end, updates, readings, wall,
                     {n: failed[n] for n in names if n in failed}, unknown_ids,
                     {n: scores[n] for n in names if scores and n in scores}, slam, given,
                     {n: maps[n] for n in names if maps and n in maps})


class _RecordedMap:
    """A SLAM filter's recorded map, seen as the filter (``landmarks()``) at the time the
    playback shows: the latest map at or before it, an empty one before the first update."""

    def __init__(self, playback: MrclamPlayback, history: MapHistory):
        self.playback, self.history = playback, history

    def landmarks(self) -> LandmarkMap:
        lm = self.history.at(float(self.playback.times[self.playback.k]))
        return lm if lm is not None else LandmarkMap(None, np.zeros((0, 2)), np.zeros((0, 2, 2)))


#: Readings stay drawn this long after their time stamp [s] (they arrive a few per second).
READING_SHOW_S = 0.3


class MrclamPlayback:
    """A finished MRCLAM run seen one display tick of ``scenario.dt`` at a time: a
    :class:`~beacon_sim.runs.scene.Scene` with a timeline, for the replay window.

    The filters ran on the real data first; this only looks the results up: the ground truth
    interpolated to the tick, each filter's latest estimate at or before it, and the landmark
    readings of the last ``READING_SHOW_S`` seconds.
    """

    def __init__(self, run: MrclamRun):
        self.run = run
        self.scenario = sc = run.scenario
        self.names = list(run.tracks)
        self.specs: list[str] = []
        self.seed, self.autopilot = 0, False
        self.params: dict[str, dict[str, Any]] = {}
        self.visible = {n: True for n in self.names}
        self.status = {n: FilterStatus(n) for n in self.names}
        dt = sc.dt
        self.total_ticks = math.floor((run.t_end - run.t_start) / dt + 1e-9)
        self.times = run.t_start + dt * np.arange(self.total_ticks + 1)
        self.truth, _ = run.data.truth_at(self.times)
        # Index of each filter's latest estimate at or before each display tick.
        self.index = {n: np.searchsorted(np.array(tr.times), self.times, side="right") - 1
                      for n, tr in run.tracks.items()}
        ms = run.data.measurements
        self.meas = ms[(ms[:, 0] > run.t_start) & (ms[:, 0] <= run.t_end)]
        self.od = run.data.odometry
        self.shown: dict[str, tuple[np.ndarray, np.ndarray] | None] = {}
        #: The SLAM filters' maps as the window's map layer reads them (``landmarks()`` at
        #: the displayed time); only a ``--slam`` run shown in the window has them.
        self.filters = {n: _RecordedMap(self, h) for n, h in run.map_history.items()}
        self.seek(0)

    # --- time -------------------------------------------------------------------------------
    @property
    def at_end(self) -> bool:
        return self.k >= self.total_ticks

    @property
    def tick_count(self) -> int:
        return self.k

    @property
    def time(self) -> float:
        return float(self.times[self.k] - self.run.t_start)

    @property
    def true_pose(self) -> np.ndarray:
        return self.truth[self.k]

    @property
    def drive_mode(self) -> str:
        return f"MRCLAM {self.run.data.folder.name} robot {self.run.data.robot}"

    def seek(self, tick: int, keep_flips: Set[str] = frozenset()) -> None:
        """Jump to ``tick``; the trails are rebuilt from the start (cheap: lookups only).
        Shown / hidden filters stay as they are (``keep_flips`` is for rebuilt scenes)."""
        self.k = min(max(int(tick), 0), self.total_ticks)
        self.truth_trail = Trail()
        self.trails = {n: Trail() for n in self.names}
        for k in range(self.k):  # the trails up to (not including) the tick shown
            self.truth_trail.add(self.truth[k])
            for n, tr in self.run.tracks.items():
                i = int(self.index[n][k])
                if i >= 0:
                    self.trails[n].add(tr.means[i])
        self._show()

    def tick(self) -> tuple[EventRecord, ...]:
        """One display tick forward; returns its events (none: the data has no kidnaps)."""
        self.k = min(self.k + 1, self.total_ticks)
        self._show()
        return ()

    def _show(self) -> None:
        k, truth = self.k, self.truth[self.k]
        self.truth_trail.add(truth)
        for n, tr in self.run.tracks.items():
            i = int(self.index[n][k])
            st = self.status[n]
            st.failed = tr.failed if i >= len(tr.means) - 1 else None
            self.shown[n] = None
            if i >= 0:
                mean, cov = tr.means[i], tr.covs[i]
                self.shown[n] = (mean, cov)
                self.trails[n].add(mean)
                st.measure(mean, cov, truth)

    # --- what the window reads ----------------------------------------------------------------
    def next_control(self) -> Control:
        """The odometry command in force at the displayed time [m/s, rad/s]."""
        i = int(np.searchsorted(self.od[:, 0], self.times[self.k], side="right")) - 1
        return Control(float(self.od[max(i, 0), 1]), float(self.od[max(i, 0), 2]))

    def readings(self) -> list[Measurement]:
        t = self.times[self.k]
        lo, hi = np.searchsorted(self.meas[:, 0], [t - READING_SHOW_S, t], side="right")
        if hi <= lo:
            return []
        rows = self.meas[lo:hi]
        return [Measurement("mrclam", "range_bearing", rows[:, 2:4].copy(), rows[:, 1].astype(int))]

    def seen_ids(self) -> set[int]:
        return {int(i) for m in self.readings() for i in m.beacon_ids}

    def belief(self, name: str) -> Belief | None:
        est = self.shown.get(name)
        return None if est is None else GaussianBelief(est[0], est[1])

    def estimate(self, name: str) -> tuple[np.ndarray, np.ndarray] | None:
        return self.shown.get(name)

    def marks(self) -> list[tuple[int, str]]:
        return []  # no user commands in a data set

    def trail(self, name: str) -> Trail:
        """Filter ``name``'s estimate trail."""
        return self.trails[name]

    def clear_trails(self) -> None:
        """Forget every trail, keep the current points."""
        self.truth_trail = Trail()
        self.truth_trail.add(self.true_pose)
        self.trails = {n: Trail() for n in self.names}
        for n, est in self.shown.items():
            if est is not None:
                self.trails[n].add(est[0])

    def close(self) -> None:
        """Nothing to close: the run is finished."""
