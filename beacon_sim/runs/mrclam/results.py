"""What a MRCLAM run gives back: each filter's track of each robot (:class:`MrclamTrack`),
the run (:class:`MrclamRun`), its scores against the ground truth and its JSON form."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from beacon_sim.core.metrics import chi2_quantile, nees, pose_errors, summary
from beacon_sim.core.scenario import Scenario, TeamScenario
from beacon_sim.io.mrclam import MrclamData
from beacon_sim.runs.headless import ACCURACY_KEYS
from beacon_sim.runs.mrclam.associations import AssociationCount
from beacon_sim.runs.mrclam.calibration import Calibration
from beacon_sim.runs.mrclam.map_history import MapHistory

#: Seed 001's UKF figures on MRCLAM (Table II), m^2, m^2, rad^2.
SEED_001_UKF_MSE = (0.0119, 0.0078, 0.0571)
SEED_001_EKF_MSE = (1.7875, 1.889, 7.7997)


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
