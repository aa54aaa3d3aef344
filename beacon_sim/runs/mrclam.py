"""Real robot data: one robot of a UTIAS MRCLAM data set run through any filter.

- The noise the filters are told comes from the data (:func:`calibrate`): odometry against
  ground truth and measurement residuals against ground truth, with robust statistics.
- Odometry and measurements are interleaved by time stamp (seed 001 section III.C): the
  filters predict with the latest command up to each reading's time, update, and go on
  (:func:`run_mrclam`).
- :class:`MrclamPlayback` shows a finished run one display tick at a time, for the window.

Reading the files: beacon_sim/io/mrclam.py. Frames and units: metres, radians, world frame
of the data set (Vicon), bearings relative to the heading and wrapped to [-pi, pi).
"""

from __future__ import annotations

import functools
import math
import time
import traceback
from collections.abc import Mapping, Set
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.drivers import KeyboardSpec
from beacon_sim.core.keyboard_drive import KeyboardLimits
from beacon_sim.core.measurement_models import relative_bearing
from beacon_sim.core.metrics import chi2_quantile, nees, pose_errors, summary
from beacon_sim.core.motion import MotionNoise
from beacon_sim.core.scenario import InitialBelief, Scenario
from beacon_sim.core.sensors import SensorNoise, SensorSpec
from beacon_sim.core.types import Beacon, Control, EventRecord, Measurement
from beacon_sim.core.world import World
from beacon_sim.filters.base import Belief, Filter, GaussianBelief
from beacon_sim.filters.registry import MRCLAM_DEFAULTS
from beacon_sim.filters.registry import MRCLAM_GATE_CHI2 as MRCLAM_GATE_CHI2  # re-exported
from beacon_sim.filters.runner import HEADLESS_STEP_LIMIT_S, guarded_call, one_line, validate_estimate
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
        e_d = fwd - (s[sub::sub] - s[:-1:sub])
        e_a = wrap(turn - (a[sub::sub] - a[:-1:sub]))
        good = ok[:-1].reshape(n_win, sub).all(axis=1) & ok[1:].reshape(n_win, sub).all(axis=1)
        e_d, e_a = e_d[good], e_a[good]
        s_d, s_a = rms(e_d), rms(e_a)
        stats.update(windows=int(good.sum()), fwd_err_median_m=float(np.median(e_d)),
                     fwd_err_std_m=s_d, fwd_err_robust_std_m=robust_std(e_d),
                     turn_err_median_rad=float(np.median(e_a)), turn_err_std_rad=s_a,
                     turn_err_robust_std_rad=robust_std(e_a))
    else:
        s_d, s_a = 0.01 * math.sqrt(window_s), 0.02 * math.sqrt(window_s)
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
    return Calibration(motion, sensor, step_dt, window_s, stats, outlier_rate)


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
    stats = {"fwd_err_std_m": s_d, "turn_err_std_rad": s_a, "range_err_std_m": s_r,
             "bearing_err_std_rad": s_b, "outlier_rate": outlier_rate,
             "windows": float(sum(c.stats.get("windows", 0) for c in cals)),
             "readings": float(reads.sum())}
    return Calibration(motion, sensor, step_dt, window_s, stats, outlier_rate,
                       source=f"calibrated on other runs ({names}), not on the scored run")


def other_runs(data: MrclamData, robots: tuple[int, ...] = DATASET_ROBOTS) -> list[MrclamData]:
    """The other robots of ``data``'s data set folder that it holds (a folder may hold one)."""
    from beacon_sim.io.mrclam import load_mrclam

    others = []
    for r in robots:
        if r != data.robot and (data.folder / f"Robot{r}_Groundtruth.dat").is_file():
            others.append(load_mrclam(data.folder, r))
    return others


def leave_one_robot_out(data: MrclamData, t_end: float | None = None) -> Calibration:
    """:func:`pooled_calibration` from the other robots of ``data``'s data set folder; when
    the folder holds no other robot, the scored run's own calibration, labelled so."""
    others = other_runs(data)
    if not others:
        return replace(calibrate(data, t_end),
                       source="fitted on the scored run's own ground truth: the folder holds no "
                              "other robot to calibrate from")
    return pooled_calibration(data, others)


#: How a MRCLAM run's noise is calibrated: from the data set's other robots (the default),
#: or from the scored run's own ground truth (fitted on the answer; labelled as such).
CALIBRATIONS = ("others", "self")


def calibration_for(data: MrclamData, how: str, t_end: float | None = None) -> Calibration:
    """The calibration ``how`` (one of ``CALIBRATIONS``) for ``data``'s run."""
    if how == "others":
        return leave_one_robot_out(data, t_end)
    if how == "self":
        return replace(calibrate(data, t_end),
                       source="fitted on the scored run's own ground truth (optimistic: not for scoring)")
    raise MrclamError(f"calibration {how!r}: use one of {', '.join(CALIBRATIONS)}")


# --------------------------------------------------------------------------------------------
# A scenario-like context for the filters


def mrclam_scenario(data: MrclamData, cal: Calibration, t_start: float, t_end: float) -> Scenario:
    """A :class:`Scenario` holding what the filters may know: the landmark map, the
    calibrated motion and sensor noise, and the initial belief (ground truth at the start)."""
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
                        outlier_rate=cal.outlier_rate)
    return Scenario(
        name=f"mrclam_{data.folder.name}_robot{data.robot}",
        description=f"UTIAS MRCLAM {data.folder.name}, robot {data.robot}",
        source=str(data.folder), dt=cal.step_dt, duration=t_end - t_start, seed=0, world=world,
        initial_pose=init, robot_radius=0.2, motion_noise=cal.motion, sensors=(sensor,),
        driver=KeyboardSpec(), keyboard=KeyboardLimits(), events=(),
        initial_belief=InitialBelief(mean=init, std=INITIAL_STD),
        model_motion_noise=cal.motion, model_sensors=(sensor,),
        default_filters=("ekf", "ukf", "dead_reckoning"), filter_params={},
    )


# --------------------------------------------------------------------------------------------
# Running filters on the data


@dataclass
class MrclamTrack:
    """One filter's estimates at the event times (every odometry row and every update)."""

    name: str
    filter: Filter
    times: list[float] = field(default_factory=list)
    means: list[np.ndarray] = field(default_factory=list)
    covs: list[np.ndarray] = field(default_factory=list)
    ns: int = 0
    calls: int = 0
    failed: str | None = None
    failed_time_s: float | None = None  # [s] from the start of the run
    traceback: str = ""


@dataclass
class MrclamRun:
    """The result of :func:`run_mrclam`."""

    data: MrclamData
    scenario: Scenario
    calibration: Calibration
    tracks: dict[str, MrclamTrack]
    t_start: float
    t_end: float
    updates: int
    readings: int
    wall_s: float

    def evaluate(self) -> dict[str, dict[str, Any]]:
        """Per-axis MSE, RMSE and ANEES of each filter where ground truth exists."""
        out: dict[str, dict[str, Any]] = {}
        for name, tr in self.tracks.items():
            row: dict[str, Any] = {}
            if tr.failed:  # no score for a filter that failed
                row.update(dict.fromkeys(ACCURACY_KEYS))
            elif tr.means:
                times = np.array(tr.times)
                truth, ok = self.data.truth_at(times)
                if ok.any():
                    means, covs = np.array(tr.means)[ok], np.array(tr.covs)[ok]
                    row.update(summary(means, covs, truth[ok]))
                    e = pose_errors(means, truth[ok])
                    v = nees(e, covs)
                    row["nees_above_99"] = float(np.mean(v > chi2_quantile(0.99, 3)))
                    steps = np.hypot(*np.diff(np.array(tr.means)[:, :2], axis=0).T)
                    row["largest_jump_m"] = float(steps.max()) if steps.size else 0.0
                row["evaluated_s"] = float(np.sum(np.diff(times)[ok[1:]])) if len(times) > 1 else 0.0
            row["us_per_step"] = tr.ns / 1e3 / max(tr.calls, 1)
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
        cal = self.calibration
        return {
            "dataset": str(self.data.folder), "robot": self.data.robot,
            "t_start": self.t_start, "duration_s": self.t_end - self.t_start,
            "odometry_rows": int(np.sum((self.data.odometry[:, 0] >= self.t_start)
                                        & (self.data.odometry[:, 0] <= self.t_end))),
            "updates": self.updates, "readings": self.readings, "dropped": self.data.dropped,
            "noise": {"v_std": cal.motion.v_std, "omega_std": cal.motion.omega_std,
                      "range_std": cal.sensor.range_std, "bearing_std": cal.sensor.bearing_std,
                      "step_dt": cal.step_dt},
            "calibration": cal.stats,
            "calibration_source": cal.source,
            "filters": self.evaluate(),
            "wall_s": self.wall_s,
        }


def _predict_all(tracks, control: Control, dt: float, max_step: float) -> None:
    if dt <= 0:
        return
    n = max(1, math.ceil(dt / max_step - 1e-9))
    h = dt / n
    for tr in tracks:
        if tr.failed:
            continue
        a = time.perf_counter_ns()

        def run(tr=tr) -> None:
            for _ in range(n):
                tr.filter.predict(control, h)
        # a filter that fails (raises, exits, hangs) is switched off; the others go on
        _, why, tb = guarded_call(run, HEADLESS_STEP_LIMIT_S)
        if why is not None:
            tr.failed, tr.traceback = f"predict: {why}", tb
        tr.ns += time.perf_counter_ns() - a
        tr.calls += n


def run_mrclam(data: MrclamData, filters: list[str] | None = None, duration: float | None = None,
               params: dict[str, dict[str, Any]] | None = None,
               calibration: Calibration | str | None = "others") -> MrclamRun:
    """Run filters over one robot's data, interleaving odometry and readings by time stamp.

    Each filter starts at the ground truth of the first odometry time (``INITIAL_STD``),
    predicts with the latest command up to each reading's time stamp (in steps of at most
    the median odometry interval: long gaps are split), updates with all readings of that
    stamp, and goes on. Built-in filters get ``MRCLAM_PARAMS`` (the EKF's and UKF's
    chi-square gate, the particle filter's settings) unless ``params`` set them; the particle
    and grid filters weigh readings with the calibrated outlier mixture (docs/replay.md).
    """
    from beacon_sim.filters.loading import (
        FilterError,
        build_filter,
        check_param_names,
        filter_display_name,
        filter_names,
    )

    od = data.odometry
    t_start = data.t0
    t_end = float(od[-1, 0]) if duration is None else min(float(od[-1, 0]), t_start + duration)
    if calibration is None:
        calibration = "self"
    cal = calibration_for(data, calibration, t_end) if isinstance(calibration, str) else calibration
    scenario = mrclam_scenario(data, cal, t_start, t_end)
    specs = list(scenario.default_filters if filters is None else filters)
    check_param_names(params, specs)
    tracks: dict[str, MrclamTrack] = {}
    for name, spec in zip(filter_names(specs), specs, strict=True):
        p = dict((params or {}).get(filter_display_name(spec), {}))
        for key, value in MRCLAM_PARAMS.get(spec, {}).items():
            p.setdefault(key, value)
        try:
            tracks[name] = MrclamTrack(name, build_filter(spec, scenario, seed=0, name=name, params=p))
        except FilterError:
            raise  # the user named something that cannot work: one line, exit 2
        except Exception as exc:  # the filter's own __init__ or reset failed: switched off
            tracks[name] = MrclamTrack(name, None, failed=f"construction failed: {one_line(exc)}",  # type: ignore[arg-type]
                                       failed_time_s=0.0, traceback=traceback.format_exc())

    ms = data.measurements
    ms = ms[(ms[:, 0] > t_start) & (ms[:, 0] <= t_end)]
    group_t, group_start = np.unique(ms[:, 0], return_index=True)
    group_end = np.append(group_start[1:], len(ms))
    od_sel = od[(od[:, 0] > t_start) & (od[:, 0] <= t_end)]
    first = int(np.searchsorted(od[:, 0], t_start, side="right")) - 1
    u = Control(float(od[first, 1]), float(od[first, 2]))
    max_step = cal.step_dt * 1.5
    active = list(tracks.values())

    def record(t: float) -> None:
        for tr in active:
            if not tr.failed:
                raw, why, tb = guarded_call(tr.filter.estimate, HEADLESS_STEP_LIMIT_S)
                est = validate_estimate(raw) if why is None else f"estimate(): {why}"
                if isinstance(est, str):
                    tr.failed, tr.traceback = est, tb
                else:
                    tr.times.append(t)
                    tr.means.append(est[0])
                    tr.covs.append(est[1])
            if tr.failed and tr.failed_time_s is None:
                tr.failed_time_s = t - t_start

    t0 = time.perf_counter()
    record(t_start)
    t = t_start
    i_od = i_me = 0
    n_od, n_me = len(od_sel), len(group_t)
    updates = 0
    while i_od < n_od or i_me < n_me:
        t_od = od_sel[i_od, 0] if i_od < n_od else math.inf
        t_me = group_t[i_me] if i_me < n_me else math.inf
        t_next = min(t_od, t_me)
        _predict_all(active, u, t_next - t, max_step)
        t = t_next
        if t_me <= t_od:
            a, b = group_start[i_me], group_end[i_me]
            m = Measurement(SENSOR_NAME, "range_bearing", ms[a:b, 2:4].copy(),
                            ms[a:b, 1].astype(int))
            for tr in active:
                if tr.failed:
                    continue
                c = time.perf_counter_ns()
                _, why, tb = guarded_call(functools.partial(tr.filter.update, [m]),
                                          HEADLESS_STEP_LIMIT_S)
                if why is not None:
                    tr.failed, tr.traceback = f"update: {why}", tb
                tr.ns += time.perf_counter_ns() - c
            updates += 1
            i_me += 1
        else:
            u = Control(float(od_sel[i_od, 1]), float(od_sel[i_od, 2]))
            i_od += 1
        record(t)
    wall = time.perf_counter() - t0
    return MrclamRun(data, scenario, cal, tracks, t_start, t_end, updates, len(ms), wall)


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
