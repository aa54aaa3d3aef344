"""MRCLAM's five robots at once (issue 18): every robot's own filter against the team
filters that also use the robots' sightings of each other.

- Each robot's noise is calibrated from its own data as in the single-robot run
  (runs/mrclam.py ``calibrate``); a robot sighting is told the same noise as that robot's
  landmark readings (the same camera and barcode reader).
- One common clock of ``dt`` seconds from the latest first odometry time of the five:
  every tick each robot moves by the exact integral of its piecewise-constant odometry
  commands over the tick (v = ds/dt, omega = da/dt), and the readings stamped inside the
  tick update at its end (a time error below dt: 4 mm at MRCLAM's 0.08 m/s for 0.05 s).
- Filters: ``independent`` (one EKF per robot, landmarks only: the baseline), ``centralised``
  (joint EKF), ``ci`` (covariance intersection), with the single-robot run's 99.9 %
  chi-square gate on every reading and message. Each starts at the ground truth.
- Figures per robot where its ground truth exists: position and heading RMSE, ANEES.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from beacon_sim.core.metrics import summary
from beacon_sim.core.sensors import SensorSpec
from beacon_sim.core.team_scenario import RobotSensorSpec
from beacon_sim.core.types import Control, Measurement
from beacon_sim.filters.base import FilterContext, GaussianBelief
from beacon_sim.filters.runner import HEADLESS_STEP_LIMIT_S, failure_text
from beacon_sim.filters.team import TEAM_FILTERS, TeamContext, TeamMember
from beacon_sim.filters.team_runner import JointRunner, build_team_filters, validate_team_estimates
from beacon_sim.io.mrclam import ROBOT_SUBJECTS, MrclamData, load_mrclam
from beacon_sim.runs.mrclam import (
    INITIAL_STD,
    MRCLAM_GATE_CHI2,
    SENSOR_NAME,
    Calibration,
    _command_integrals,
    calibrate,
    mrclam_scenario,
)

#: The name of the robot-sighting "sensor" in a team MRCLAM run.
SIGHTING_SENSOR = "camera_robots"
TEAM_MRCLAM_FILTERS = ("independent", "centralised", "decentralised", "ci")


@dataclass
class TeamMrclamRun:
    data: list[MrclamData]
    calibrations: list[Calibration]
    times: np.ndarray
    tracks: dict[str, tuple[np.ndarray, np.ndarray]]  # name -> means (T, N, 3), covs (T, N, 3, 3)
    us_per_step: dict[str, float]
    wall_s: float
    failed: dict[str, str] = field(default_factory=dict)  # name -> why it was switched off (no score)

    def evaluate(self) -> dict[str, dict[int, dict[str, float]]]:
        """Per filter, per robot (subject 1-5): summary() where ground truth exists."""
        out: dict[str, dict[int, dict[str, float]]] = {}
        for name, (means, covs) in self.tracks.items():
            out[name] = {}
            for i, d in enumerate(self.data):
                truth, ok = d.truth_at(self.times)
                out[name][d.robot] = summary(means[ok, i], covs[ok, i], truth[ok])
        return out

    def as_json(self) -> dict[str, Any]:
        return {
            "dataset": str(self.data[0].folder), "robots": [d.robot for d in self.data],
            "duration_s": float(self.times[-1] - self.times[0]),
            "landmark_readings": {d.robot: len(d.measurements) for d in self.data},
            "robot_sightings": {d.robot: len(d.sightings) for d in self.data},
            "filters": {n: {str(k): v for k, v in rows.items()} for n, rows in self.evaluate().items()},
            "us_per_step": self.us_per_step, "wall_s": self.wall_s, "failed": self.failed,
        }


def team_mrclam_context(name: str, data: list[MrclamData], cals: list[Calibration], t_start: float,
                        t_end: float, dt: float) -> TeamContext:
    """The team filter context: per robot the calibrated motion noise, the landmark camera and
    the sighting sensor with the same noise, gates on."""
    members = []
    world = None
    for d, cal in zip(data, cals, strict=True):
        sc = mrclam_scenario(d, cal, t_start, t_end)
        world = sc.world if world is None else world
        cam = SensorSpec(name=SENSOR_NAME, kind="range_bearing", period=dt, noise=cal.sensor)
        ctx = FilterContext(name=f"{name}/robot{d.robot}", world=sc.world, dt=dt, motion_noise=cal.motion,
                            sensors=(cam,), params={"gate_chi2": MRCLAM_GATE_CHI2})
        rs = RobotSensorSpec(SIGHTING_SENSOR, "robot_range_bearing", period=dt, noise=cal.sensor)
        members.append(TeamMember(d.robot, ctx, (rs,)))
    assert world is not None
    params = {} if name == "independent" else {"gate_chi2": MRCLAM_GATE_CHI2}
    return TeamContext(name, world, dt, tuple(members), params)


def run_team_mrclam(folder, filters: list[str] | None = None, duration: float | None = None,
                    dt: float = 0.05, robots=ROBOT_SUBJECTS) -> TeamMrclamRun:
    """Run team filters over all robots of an MRCLAM folder (see the module docstring)."""
    data = [load_mrclam(folder, r, robot_sightings=True) for r in robots]
    t_start = max(d.t0 for d in data)
    t_end = min(float(d.odometry[-1, 0]) for d in data)
    if duration is not None:
        t_end = min(t_end, t_start + duration)
    cals = [calibrate(d, t_end) for d in data]
    n_ticks = int((t_end - t_start) // dt)
    times = t_start + dt * np.arange(n_ticks + 1)
    # commands per tick: exact integrals of the piecewise-constant odometry
    v = np.empty((n_ticks, len(data)))
    w = np.empty((n_ticks, len(data)))
    for i, d in enumerate(data):
        s, a = _command_integrals(d.odometry, times)
        v[:, i] = np.diff(s) / dt
        w[:, i] = np.diff(a) / dt
    # readings per tick: stamps in (t_k, t_k+1] update at t_k+1
    per_tick: list[dict[int, list[Measurement]]] = [{} for _ in range(n_ticks)]
    for i, d in enumerate(data):
        for rows, sensor, kind in ((d.measurements, SENSOR_NAME, "range_bearing"),
                                   (d.sightings, SIGHTING_SENSOR, "robot_range_bearing")):
            rows = rows[(rows[:, 0] > t_start) & (rows[:, 0] <= times[-1])]
            k = np.clip(np.ceil((rows[:, 0] - t_start) / dt).astype(int) - 1, 0, n_ticks - 1)
            for kk in np.unique(k):
                sel = rows[k == kk]
                # one reading per subject and tick (the first)
                _, first = np.unique(sel[:, 1], return_index=True)
                sel = sel[np.sort(first)]
                per_tick[kk].setdefault(i, []).append(
                    Measurement(sensor, kind, sel[:, 2:4].copy(), sel[:, 1].astype(np.int64)))
    initial = []
    for d in data:
        pose, _ = d.truth_at(np.array([t_start]))
        initial.append(GaussianBelief(pose[0], np.diag(np.square(INITIAL_STD))))
    names = list(TEAM_MRCLAM_FILTERS if filters is None else filters)

    def build(n: str) -> Any:
        f = TEAM_FILTERS[n](team_mrclam_context(n, data, cals, t_start, t_end, dt))
        f.reset(initial)
        return f

    built, why = build_team_filters(names, build, HEADLESS_STEP_LIMIT_S)
    runner = JointRunner(built, len(data), HEADLESS_STEP_LIMIT_S)
    for n, reason in why.items():
        runner.tracks[n].failed = f"could not be built: {reason}"
    start: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for n, f in built.items():
        if f is not None:
            checked = validate_team_estimates(f.estimates(), len(data))
            if isinstance(checked, str):
                runner.fail(n, checked)
            else:
                start[n] = checked
    t0 = time.perf_counter()
    empty: list[Measurement] = []
    for k in range(n_ticks):
        controls = [Control(float(v[k, i]), float(w[k, i])) for i in range(len(data))]
        readings = [per_tick[k].get(i, empty) for i in range(len(data))]
        runner.feed(k + 1, float(times[k + 1] - t_start), controls, dt, readings)
    wall = time.perf_counter() - t0
    tracks, failed = {}, {}
    for n in names:
        tr = runner.tracks[n]
        if tr.failed:
            failed[n] = failure_text(tr) or tr.failed
            continue
        tracks[n] = (np.concatenate([start[n][0][None], np.array(tr.means)]),
                     np.concatenate([start[n][1][None], np.array(tr.covs)]))
    return TeamMrclamRun(data, cals, times, tracks,
                         {n: runner.tracks[n].us_per_step for n in tracks}, wall, failed)
