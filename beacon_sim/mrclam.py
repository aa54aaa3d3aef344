"""Real robot data: the UTIAS MRCLAM data sets (Leung et al., IJRR 2011) run through any filter.

``beacon-sim mrclam DIR --robot N [--filter F ...] [--duration S] [--calibrate] [--json]``

- Reads ``RobotN_Odometry.dat`` (t, v, omega), ``RobotN_Measurement.dat`` (t, barcode, range,
  bearing), ``RobotN_Groundtruth.dat`` (t, x, y, theta), ``Landmark_Groundtruth.dat`` and
  ``Barcodes.dat`` of one folder (4 comment lines, CRLF, tabs or spaces). A malformed or
  missing file is an error naming the file and line.
- Barcodes are mapped to subjects through that folder's ``Barcodes.dat``; sightings of robots
  (subjects 1-5) and unknown barcodes are dropped; readings sharing a time stamp form one
  update.
- Odometry and measurements are interleaved by time stamp (seed 001 section III.C): the
  filters predict with the latest command up to each reading's time, update, and go on.
- The noise the filters are told comes from the data (:func:`calibrate`): odometry against
  ground truth and measurement residuals against ground truth, with robust statistics.
- Ground truth is interpolated to the estimate times; only times inside ground truth count.

Frames and units: metres, radians, world frame of the data set (Vicon), bearings relative to
the heading and wrapped to [-pi, pi).
"""

from __future__ import annotations

import json
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.drivers import KeyboardSpec
from beacon_sim.core.keyboard_drive import KeyboardLimits
from beacon_sim.core.metrics import summary
from beacon_sim.core.motion import MotionNoise
from beacon_sim.core.scenario import InitialBelief, Scenario
from beacon_sim.core.sensors import SensorNoise, SensorSpec
from beacon_sim.core.types import Beacon, Control, Measurement
from beacon_sim.core.world import World

#: Subjects 1-5 are the robots in every MRCLAM data set; landmarks are 6 and up.
ROBOT_SUBJECTS = range(1, 6)
SENSOR_NAME = "camera"
#: Seed 001's UKF figures on MRCLAM (Table II), m^2, m^2, rad^2.
SEED_001_UKF_MSE = (0.0119, 0.0078, 0.0571)
SEED_001_EKF_MSE = (1.7875, 1.889, 7.7997)
#: Ground-truth samples further apart than this [s] are a gap: no evaluation inside it.
MAX_TRUTH_GAP_S = 0.5
#: The window [s] over which odometry is compared with ground truth (about the time between
#: two sightings, the span a filter must predict over).
CALIBRATION_WINDOW_S = 1.0
#: Initial belief: ground truth at the start with these standard deviations [m, m, rad]
#: (local localization with a known start, as seed 001).
INITIAL_STD = (0.05, 0.05, 0.05)


class MrclamError(ValueError):
    """A missing or malformed MRCLAM file; the message names the file and line."""


# --------------------------------------------------------------------------------------------
# Reading


def read_table(path: Path, ncols: int, columns: str) -> np.ndarray:
    """Rows of ``ncols`` numbers from an MRCLAM ``.dat`` file, shape (n, ncols).

    Lines starting with ``#`` and blank lines are skipped; CRLF and tabs/spaces are fine.
    """
    if not path.is_file():
        raise MrclamError(f"{path}: missing (an MRCLAM folder holds {path.name} with columns "
                          f"{columns})")
    try:
        raw = path.read_bytes().decode("ascii")
    except UnicodeDecodeError as exc:
        line = path.read_bytes()[: exc.start].count(b"\n") + 1
        raise MrclamError(f"{path}:{line}: not a text line (byte {exc.start})") from None
    rows: list[list[float]] = []
    for n, line in enumerate(raw.splitlines(), start=1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        parts = s.split()
        if len(parts) != ncols:
            raise MrclamError(f"{path}:{n}: expected {ncols} columns ({columns}), "
                              f"found {len(parts)}: {s[:60]!r}")
        try:
            row = [float(p) for p in parts]
        except ValueError:
            raise MrclamError(f"{path}:{n}: not a number in {s[:60]!r}") from None
        if not all(math.isfinite(v) for v in row):
            raise MrclamError(f"{path}:{n}: not a finite number in {s[:60]!r}")
        rows.append(row)
    if not rows:
        raise MrclamError(f"{path}: no data rows (columns {columns})")
    return np.array(rows, dtype=float)


@dataclass
class MrclamData:
    """One robot of one MRCLAM folder, cleaned.

    Attributes
    ----------
    odometry : ndarray (n, 3)
        ``t [s], v [m/s], omega [rad/s]``, sorted by time (stable: repeated stamps kept in
        file order; the last of them governs).
    measurements : ndarray (m, 4)
        ``t [s], subject, range [m], bearing [rad]``, landmarks only, sorted by time.
    groundtruth : ndarray (g, 4)
        ``t [s], x [m], y [m], theta [rad]``, strictly increasing times.
    landmarks : dict subject -> (x, y) [m]
    dropped : dict
        Counts of rows dropped: ``robot_sightings``, ``unknown_barcodes``, ``unknown_landmarks``
        (barcode of a subject with no landmark position), ``duplicates``.
    """

    folder: Path
    robot: int
    odometry: np.ndarray
    measurements: np.ndarray
    groundtruth: np.ndarray
    landmarks: dict[int, tuple[float, float]]
    barcodes: dict[int, int]
    dropped: dict[str, int] = field(default_factory=dict)

    @property
    def t0(self) -> float:
        """Time of the first odometry row [s] (Unix epoch): the run starts there."""
        return float(self.odometry[0, 0])

    def truth_at(self, times) -> tuple[np.ndarray, np.ndarray]:
        """Ground truth interpolated to ``times``: poses (k, 3) and a mask (k,) of the times
        that lie inside the ground truth (no gap longer than ``MAX_TRUTH_GAP_S``)."""
        return interpolate_truth(self.groundtruth, np.asarray(times, dtype=float))


def interpolate_truth(gt: np.ndarray, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Linear interpolation of x, y and the unwrapped heading; heading wrapped after."""
    t = gt[:, 0]
    poses = np.empty((times.shape[0], 3))
    poses[:, 0] = np.interp(times, t, gt[:, 1])
    poses[:, 1] = np.interp(times, t, gt[:, 2])
    poses[:, 2] = wrap(np.interp(times, t, np.unwrap(gt[:, 3])))
    j = np.clip(np.searchsorted(t, times), 1, len(t) - 1)
    ok = (times >= t[0]) & (times <= t[-1]) & ((t[j] - t[j - 1]) <= MAX_TRUTH_GAP_S)
    return poses, ok


def load_mrclam(folder, robot: int) -> MrclamData:
    """Load and clean one robot of an MRCLAM data set folder."""
    folder = Path(folder)
    if not folder.is_dir():
        raise MrclamError(f"{folder}: no such folder (expected an MRCLAM data set folder)")
    if robot not in ROBOT_SUBJECTS:
        raise MrclamError(f"--robot {robot}: expected 1 to 5")
    bc = read_table(folder / "Barcodes.dat", 2, "subject, barcode")
    lm = read_table(folder / "Landmark_Groundtruth.dat", 5, "subject, x, y, sigma_x, sigma_y")
    od = read_table(folder / f"Robot{robot}_Odometry.dat", 3, "time, v, omega")
    ms = read_table(folder / f"Robot{robot}_Measurement.dat", 4, "time, barcode, range, bearing")
    gt = read_table(folder / f"Robot{robot}_Groundtruth.dat", 4, "time, x, y, theta")

    barcodes = {int(b): int(s) for s, b in bc}
    landmarks = {int(r[0]): (float(r[1]), float(r[2])) for r in lm}
    od = od[np.argsort(od[:, 0], kind="stable")]
    gt = gt[np.argsort(gt[:, 0], kind="stable")]
    _, first = np.unique(gt[:, 0], return_index=True)
    gt = gt[first]
    ms = ms[np.argsort(ms[:, 0], kind="stable")]

    subjects = np.array([barcodes.get(int(b), -1) for b in ms[:, 1]], dtype=int)
    robot_rows = np.isin(subjects, list(ROBOT_SUBJECTS))
    unknown = subjects < 0
    no_position = ~robot_rows & ~unknown & ~np.isin(subjects, list(landmarks))
    keep = ~(robot_rows | unknown | no_position)
    ms = np.column_stack([ms[:, 0], subjects, ms[:, 2], ms[:, 3]])[keep]
    # The same landmark twice at one time stamp: keep the first reading.
    seen: set[tuple[float, int]] = set()
    dup = np.zeros(len(ms), dtype=bool)
    for i, (t, s) in enumerate(zip(ms[:, 0].tolist(), ms[:, 1].astype(int).tolist(), strict=True)):
        dup[i] = (t, s) in seen
        seen.add((t, s))
    ms = ms[~dup]
    ms[:, 3] = wrap(ms[:, 3])
    dropped = {"robot_sightings": int(robot_rows.sum()), "unknown_barcodes": int(unknown.sum()),
               "unknown_landmarks": int(no_position.sum()), "duplicates": int(dup.sum())}
    return MrclamData(folder, robot, od, ms, gt, landmarks, barcodes, dropped)


# --------------------------------------------------------------------------------------------
# Noise from the data


def robust_std(x: np.ndarray) -> float:
    """1.4826 x the median absolute deviation from the median: the standard deviation of the
    Gaussian core, not inflated by the heavy tails."""
    x = np.asarray(x, dtype=float)
    if x.size == 0:
        return float("nan")
    return float(1.4826 * np.median(np.abs(x - np.median(x))))


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

    ``motion`` is per filter step of ``step_dt`` seconds (white noise equivalent to the
    error seen over ``window_s``); ``sensor`` holds the robust standard deviations of the
    range and bearing residuals.
    """

    motion: MotionNoise
    sensor: SensorNoise
    step_dt: float
    window_s: float
    stats: dict[str, float]


def calibrate(data: MrclamData, t_end: float | None = None,
              window_s: float = CALIBRATION_WINDOW_S) -> Calibration:
    """Estimate the filters' noise from the data, where ground truth exists.

    Odometry: over consecutive windows of ``window_s`` seconds, the true forward
    displacement and heading change (ground truth, in the robot frame at the window start)
    minus the integrated commands. Their robust standard deviations ``s_d`` [m] and ``s_a``
    [rad] over a window are turned into the per-step standard deviations of a white
    velocity noise with the same variance over the window: ``sigma_v = s_d / sqrt(window *
    step_dt)`` [m/s], ``sigma_omega = s_a / sqrt(window * step_dt)`` [rad/s], with
    ``step_dt`` the median odometry interval (the filters' step).

    Measurements: range and bearing residuals against the ground truth interpolated to the
    reading times; robust (MAD) standard deviations. Medians (biases), the fraction of
    bearings off by more than pi/2 and the tail fractions are reported in ``stats``.
    """
    od = data.odometry
    t_end = float(od[-1, 0]) if t_end is None else min(float(t_end), float(od[-1, 0]))
    step_dt = float(np.median(np.diff(od[:, 0]))) if len(od) > 1 else 0.01
    step_dt = step_dt if step_dt > 0 else 0.01
    start = max(data.t0, float(data.groundtruth[0, 0]))
    edges = np.arange(start, t_end, window_s)
    stats: dict[str, float] = {}
    if edges.size >= 3:
        pose, ok = data.truth_at(edges)
        s, a = _command_integrals(od, edges)
        d = np.diff(pose[:, :2], axis=0)
        th = pose[:-1, 2]
        fwd = np.cos(th) * d[:, 0] + np.sin(th) * d[:, 1]
        e_d = fwd - np.diff(s)
        e_a = wrap(np.diff(np.unwrap(pose[:, 2])) - np.diff(a))
        good = ok[:-1] & ok[1:]
        e_d, e_a = e_d[good], e_a[good]
        s_d, s_a = robust_std(e_d), robust_std(e_a)
        stats.update(windows=int(good.sum()), fwd_err_median_m=float(np.median(e_d)),
                     fwd_err_std_m=s_d, turn_err_median_rad=float(np.median(e_a)),
                     turn_err_std_rad=s_a)
    else:
        s_d, s_a = 0.01, 0.02
        stats["windows"] = 0
    scale = math.sqrt(window_s * step_dt)
    motion = MotionNoise(v_std=s_d / scale, omega_std=s_a / scale)

    ms = data.measurements
    ms = ms[ms[:, 0] <= t_end]
    pose, ok = data.truth_at(ms[:, 0])
    ms, pose = ms[ok], pose[ok]
    if len(ms) >= 5:
        lxy = np.array([data.landmarks[int(s)] for s in ms[:, 1]])
        dx = lxy[:, 0] - pose[:, 0]
        dy = lxy[:, 1] - pose[:, 1]
        e_r = ms[:, 2] - np.hypot(dx, dy)
        e_b = wrap(ms[:, 3] - (np.arctan2(dy, dx) - pose[:, 2]))
        flipped = np.abs(e_b) > math.pi / 2
        s_r = robust_std(e_r)
        s_b = robust_std(e_b[~flipped])
        stats.update(readings=len(ms), range_err_median_m=float(np.median(e_r)), range_err_std_m=s_r,
                     range_short_tail=float(np.mean(e_r < np.median(e_r) - 3 * s_r)),
                     range_long_tail=float(np.mean(e_r > np.median(e_r) + 3 * s_r)),
                     bearing_err_median_rad=float(np.median(e_b[~flipped])), bearing_err_std_rad=s_b,
                     bearing_flipped=float(np.mean(flipped)),
                     bearing_tail=float(np.mean(np.abs(e_b[~flipped]) > 3 * s_b)))
    else:
        s_r, s_b = 0.1, 0.05
        stats["readings"] = len(ms)
    sensor = SensorNoise(bearing_std=max(s_b, 1e-4), range_std=max(s_r, 1e-4))
    return Calibration(motion, sensor, step_dt, window_s, stats)


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
    init = tuple(float(v) for v in pose[0])
    sensor = SensorSpec(name=SENSOR_NAME, kind="range_bearing", period=cal.step_dt, noise=cal.sensor)
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
    filter: object
    times: list[float] = field(default_factory=list)
    means: list[np.ndarray] = field(default_factory=list)
    covs: list[np.ndarray] = field(default_factory=list)
    ns: int = 0
    calls: int = 0
    failed: str | None = None


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
            if tr.means:
                times = np.array(tr.times)
                truth, ok = self.data.truth_at(times)
                if ok.any():
                    row.update(summary(np.array(tr.means)[ok], np.array(tr.covs)[ok], truth[ok]))
                row["evaluated_s"] = float(np.sum(np.diff(times)[ok[1:]])) if len(times) > 1 else 0.0
            row["us_per_step"] = tr.ns / 1e3 / max(tr.calls, 1)
            for attr in ("rejected", "n_rejected", "gated"):
                value = getattr(tr.filter, attr, None)
                if isinstance(value, int | np.integer):
                    row["rejected_readings"] = int(value)
            if tr.failed:
                row["failed"] = tr.failed
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
        try:
            for _ in range(n):
                tr.filter.predict(control, h)
        except Exception as exc:  # a filter that fails is switched off; the others go on
            tr.failed = f"{type(exc).__name__}: {exc}"
        tr.ns += time.perf_counter_ns() - a
        tr.calls += n


def run_mrclam(data: MrclamData, filters: list[str] | None = None, duration: float | None = None,
               params: dict[str, dict[str, Any]] | None = None,
               calibration: Calibration | None = None) -> MrclamRun:
    """Run filters over one robot's data, interleaving odometry and readings by time stamp.

    Each filter starts at the ground truth of the first odometry time (``INITIAL_STD``),
    predicts with the latest command up to each reading's time stamp (in steps of at most
    the median odometry interval: long gaps are split), updates with all readings of that
    stamp, and goes on. No outlier gate is added: the EKF's ``gate_chi2`` stays as
    ``params`` set it (docs/replay.md shows why a gate hurts with this data's noise).
    """
    from beacon_sim.filters.loading import build_filter, filter_display_name, filter_names

    od = data.odometry
    t_start = data.t0
    t_end = float(od[-1, 0]) if duration is None else min(float(od[-1, 0]), t_start + duration)
    cal = calibration or calibrate(data, t_end)
    scenario = mrclam_scenario(data, cal, t_start, t_end)
    specs = list(scenario.default_filters if filters is None else filters)
    tracks: dict[str, MrclamTrack] = {}
    for name, spec in zip(filter_names(specs), specs, strict=True):
        p = dict((params or {}).get(filter_display_name(spec), {}))
        tracks[name] = MrclamTrack(name, build_filter(spec, scenario, seed=0, name=name, params=p))

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
            if tr.failed:
                continue
            try:
                mean, cov = tr.filter.estimate()
            except Exception as exc:
                tr.failed = f"{type(exc).__name__}: {exc}"
                continue
            tr.times.append(t)
            tr.means.append(np.array(mean, dtype=float))
            tr.covs.append(np.array(cov, dtype=float))

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
                try:
                    tr.filter.update([m])
                except Exception as exc:
                    tr.failed = f"{type(exc).__name__}: {exc}"
                tr.ns += time.perf_counter_ns() - c
            updates += 1
            i_me += 1
        else:
            u = Control(float(od_sel[i_od, 1]), float(od_sel[i_od, 2]))
            i_od += 1
        record(t)
    wall = time.perf_counter() - t0
    return MrclamRun(data, scenario, cal, tracks, t_start, t_end, updates, len(ms), wall)


# --------------------------------------------------------------------------------------------
# Command line


def _print_calibration(data: MrclamData, cal: Calibration) -> None:
    s = cal.stats
    print(f"MRCLAM {data.folder} robot {data.robot}: noise from the data")
    print(f"  dropped readings: {data.dropped}")
    if s.get("windows"):
        print(f"  odometry vs ground truth over {s['windows']} windows of {cal.window_s:g} s: "
              f"forward error median {s['fwd_err_median_m']:+.4f} m, robust std "
              f"{s['fwd_err_std_m']:.4f} m; turn error median {s['turn_err_median_rad']:+.4f} rad, "
              f"robust std {s['turn_err_std_rad']:.4f} rad")
    if s.get("readings", 0) >= 5:
        print(f"  {s['readings']} readings vs ground truth: range error median "
              f"{s['range_err_median_m']:+.4f} m, robust std {s['range_err_std_m']:.4f} m, "
              f"{100 * s['range_short_tail']:.1f} % too short and {100 * s['range_long_tail']:.1f} % "
              f"too long beyond 3 std")
        print(f"  bearing error median {s['bearing_err_median_rad']:+.4f} rad, robust std "
              f"{s['bearing_err_std_rad']:.4f} rad, {100 * s['bearing_tail']:.1f} % beyond 3 std, "
              f"{100 * s['bearing_flipped']:.1f} % off by more than pi/2")
    m = cal.motion
    print(f"  filters told (per {cal.step_dt:g} s step): v_std = {m.v_std:.4f} m/s, omega_std = "
          f"{m.omega_std:.4f} rad/s, range_std = {cal.sensor.range_std:.4f} m, bearing_std = "
          f"{cal.sensor.bearing_std:.4f} rad")


def _print_run(d: dict[str, Any]) -> None:
    from beacon_sim.cli import _fmt

    print(f"MRCLAM {d['dataset']} robot {d['robot']}: {d['duration_s']:.1f} s, "
          f"{d['odometry_rows']} odometry rows, {d['updates']} updates with {d['readings']} "
          f"landmark readings (dropped: {', '.join(f'{k} {v}' for k, v in d['dropped'].items())})")
    n = d["noise"]
    print(f"noise from the data (beacon-sim mrclam ... --calibrate): v_std {n['v_std']:.4f} m/s, "
          f"omega_std {n['omega_std']:.4f} rad/s per {n['step_dt']:g} s, range_std "
          f"{n['range_std']:.4f} m, bearing_std {n['bearing_std']:.4f} rad")
    print(f"{'filter':<16}{'MSE x m2':>10}{'MSE y m2':>10}{'MSE th rad2':>12}{'pos RMSE m':>11}"
          f"{'head RMSE':>10}{'ANEES':>9}{'us/step':>9}")
    for name, r in d["filters"].items():
        if "failed" in r:
            print(f"{name:<16}FAILED: {r['failed']}")
            continue
        if "mse_x" not in r:
            print(f"{name:<16}no estimate inside the ground truth")
            continue
        print(f"{name:<16}{r['mse_x']:>10.4f}{r['mse_y']:>10.4f}{r['mse_theta']:>12.4f}"
              f"{r['pos_rmse_m']:>11.4f}{r['heading_rmse_rad']:>10.4f}{_fmt(r['anees'], '.1f'):>9}"
              f"{r['us_per_step']:>9.1f}")
    u, e = SEED_001_UKF_MSE, SEED_001_EKF_MSE
    print(f"{'seed 001 UKF':<16}{u[0]:>10.4f}{u[1]:>10.4f}{u[2]:>12.4f}   (paper, Table II)")
    print(f"{'seed 001 EKF':<16}{e[0]:>10.4f}{e[1]:>10.4f}{e[2]:>12.4f}   (paper, Table I)")


def mrclam_command(args) -> int:
    """``beacon-sim mrclam DIR --robot N``: run filters on real data and print seed 001's table."""
    from beacon_sim.cli import UsageError, _filter_params

    duration = getattr(args, "duration", None)
    if duration is not None and not (duration > 0 and math.isfinite(duration)):
        raise UsageError(f"--duration {duration}: expected a positive number of seconds")
    try:
        data = load_mrclam(args.dir, args.robot)
    except MrclamError as exc:
        raise UsageError(str(exc)) from None
    if getattr(args, "calibrate", False):
        t_end = None if duration is None else data.t0 + duration
        cal = calibrate(data, t_end)
        if args.json:
            print(json.dumps({"dataset": str(data.folder), "robot": data.robot,
                              "dropped": data.dropped, "step_dt": cal.step_dt,
                              "motion_noise": {"v_std": cal.motion.v_std,
                                               "omega_std": cal.motion.omega_std},
                              "sensor_noise": {"range_std": cal.sensor.range_std,
                                               "bearing_std": cal.sensor.bearing_std},
                              "stats": cal.stats}))
        else:
            _print_calibration(data, cal)
        return 0
    show = None
    if not args.headless:
        try:
            from beacon_sim.app.mrclam import show_mrclam as show
        except ImportError:
            print("note: the window has no MRCLAM view; running headless", file=sys.stderr)
    try:
        run = run_mrclam(data, args.filters, duration, _filter_params(args))
    except MrclamError as exc:
        raise UsageError(str(exc)) from None
    d = run.as_json()
    if args.json:
        print(json.dumps(d, default=float))
    else:
        _print_run(d)
    for tr in run.tracks.values():
        if tr.failed:
            print(f"filter {tr.name} failed: {tr.failed}", file=sys.stderr)
    return 0 if show is None else show(run, args)
