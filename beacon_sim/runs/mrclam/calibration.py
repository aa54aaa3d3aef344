"""The noise a MRCLAM run's filters are told, estimated from the data: odometry against ground
truth and reading residuals against ground truth with robust statistics (:func:`calibrate`),
pooled over other runs (:func:`pooled_calibration`), and inflated for the Gaussian filters
(:func:`inflated`). Units: metres, radians, seconds; the data set's world frame."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.measurement_models import relative_bearing
from beacon_sim.core.motion import MotionNoise
from beacon_sim.core.sensors import SensorNoise
from beacon_sim.filters.registry import MRCLAM_ROBUST
from beacon_sim.hosting.loading import split_label
from beacon_sim.hosting.team_specs import member_spec
from beacon_sim.io.mrclam import MrclamData, MrclamError

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


def command_integrals(od: np.ndarray, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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
        s, a = command_integrals(od, fine)
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
