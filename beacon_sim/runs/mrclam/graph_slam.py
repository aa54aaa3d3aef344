"""Graph SLAM on one MRCLAM robot (``mrclam --slam --graph``): the run's odometry and
readings, fed exactly as to the filters, turned into a factor graph and solved over the
whole run, beside EKF-SLAM and FastSLAM (docs/slam.md).

- The steps are the ones :func:`~beacon_sim.runs.mrclam.feeding.feed_by_time_stamps` feeds
  (each command held up to the next odometry row or reading); ``runs/graph_slam.py`` makes
  the graph: a pose node at every reading's time stamp and at least every
  :data:`GRAPH_MAX_GAP` steps, odometry edges with the noise EKF-SLAM is told (the
  calibration from the other robots, inflated), a range-bearing edge per reading with a
  barcode, the start pose fixed (the gauge, as the filters' known start).
- Solved by Levenberg-Marquardt as the graph grows (:func:`solve_incrementally`,
  :data:`GRAPH_CHUNK` poses at a time: from dead reckoning alone the solver fell into a map
  turned by 98 degrees on robot 2), then once more without the readings whose chi2 at the
  optimum passes the filters' gate (``MRCLAM_GATE_CHI2``).
- The result is one more track (:data:`GRAPH_NAME`): the poses at their times with their
  marginal covariances, and a map object whose ``landmarks()`` gives the landmarks with
  theirs, so it is scored as the SLAM filters are. Metres, radians, the data set's frame.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import replace
from typing import cast

import numpy as np

from beacon_sim.core.team import TeamStep
from beacon_sim.core.types import Step
from beacon_sim.filters.base import LandmarkMap
from beacon_sim.filters.graph.incremental import IncrementalReport, solve_incrementally
from beacon_sim.filters.graph.solver import marginals
from beacon_sim.hosting.team_runner import TeamRunner
from beacon_sim.io.mrclam import MrclamData
from beacon_sim.runs.graph_slam import drive_graph
from beacon_sim.runs.mrclam.calibration import Calibration, inflated
from beacon_sim.runs.mrclam.feeding import feed_by_time_stamps
from beacon_sim.runs.mrclam.map_history import MapHistory
from beacon_sim.runs.mrclam.results import MrclamTrack
from beacon_sim.runs.mrclam.scenario import INITIAL_STD, MRCLAM_GATE_CHI2, mrclam_scenario

#: The track's name in a MRCLAM run.
GRAPH_NAME = "graph_slam"
#: The longest stretch [steps] between pose nodes without a reading (about 0.5 s of data).
GRAPH_MAX_GAP = 50
#: Poses added between two solves as the graph grows.
GRAPH_CHUNK = 100
#: How long [s] after an odometry row's time stamp the robot seems to carry it out: on
#: Dataset 6 the true turn over each second fits the commanded turn best (least squares, one
#: scale per robot) with the commands delayed by 0.225, 0.225, 0.175, 0.225 and 0.275 s
#: (robots 1-5; RMS residual 1.2-1.5 deg/s against 1.8-3.0 undelayed; the median of any
#: four is 0.225 s). Not the default (``graph_slam_track``'s ``command_delay_s`` is 0, the
#: filters' own steps): graph SLAM with it moved the maps' turn from -6.4 to -2.8 degrees on
#: robot 4 but from +0.8 to +5.8 on robot 3 (docs/slam.md, "Graph SLAM on MRCLAM").
COMMAND_DELAY_S = 0.225


class _StepRecorder:
    """Stands in for a runner: keeps each step fed (the robot's)."""

    def __init__(self) -> None:
        self.steps: list[Step] = []

    def feed(self, step: TeamStep) -> None:
        self.steps.append(step.steps[0])


class GraphSlamMap:
    """The solved graph's map, reported as a SLAM filter reports its own (``landmarks()``),
    and what the solve did (``report``; ``rejected``: the readings dropped as outliers;
    ``dead_reckoned``: the pose nodes (n, 3) from the commands alone, the initial values;
    ``first_reading``: the first pose node with a reading, whose solved pose is its dead
    reckoning and sets the map's frame, see ``FactorGraph.first_landmark_pose``)."""

    def __init__(self, ids: np.ndarray, means: np.ndarray, covs: np.ndarray, report: IncrementalReport,
                 dead_reckoned: np.ndarray | None = None, first_reading: int | None = None):
        self._map = LandmarkMap(ids, means, covs)
        self.report = report
        self.rejected = report.dropped
        self.dead_reckoned = dead_reckoned
        self.first_reading = first_reading

    def landmarks(self) -> LandmarkMap:
        return self._map


def delayed(data: MrclamData, delay_s: float) -> MrclamData:
    """``data`` with every odometry row carried out ``delay_s`` [s] after its time stamp (the
    first row's command held from its own stamp until then)."""
    if delay_s == 0.0:
        return data
    od = data.odometry.copy()
    od[:, 0] += delay_s
    return replace(data, odometry=np.vstack([data.odometry[:1], od]))


def recorded_steps(data: MrclamData, cal: Calibration, t_start: float, t_end: float,
                   command_delay_s: float = 0.0) -> list[Step]:
    """The steps a one-robot run feeds its filters (by time stamp, with barcodes), the
    commands carried out ``command_delay_s`` [s] after their time stamps."""
    rec = _StepRecorder()
    feed_by_time_stamps(cast(Sequence[TeamRunner], [rec]), delayed(data, command_delay_s), cal,
                        t_start, t_end)
    return rec.steps


def graph_slam_track(data: MrclamData, cal: Calibration, t_start: float, t_end: float,
                     command_delay_s: float = 0.0, pose_covariances: bool = True
                     ) -> tuple[MrclamTrack, MapHistory]:
    """Graph SLAM over one robot's run from ``t_start`` to ``t_end`` [s] told noise ``cal``
    (inflated as the Gaussian filters are), the commands delayed by ``command_delay_s``: its
    track (pose nodes at their data set times, marginal covariances; ``us_per_step``: CPU of
    building and solving per step fed) and its map as a one-entry history at the run's end
    (the window draws it). ``pose_covariances`` False: the poses' marginals are not computed
    (NaN; most of the CPU of a whole run: about 45 s for robot 4's 2,240 poses), the
    landmarks' are."""
    c0 = time.process_time()
    steps = recorded_steps(data, cal, t_start, t_end, command_delay_s)
    scenario = mrclam_scenario(data, inflated(cal), t_start, t_end, map_known=False)
    dg = drive_graph(scenario, steps, GRAPH_MAX_GAP)
    solved, report = solve_incrementally(dg.graph, GRAPH_CHUNK, "lm", outlier_chi2=MRCLAM_GATE_CHI2)
    pose_covs, mark_covs = marginals(solved, None if pose_covariances else [0])
    if not pose_covariances:
        pose_covs = np.full((solved.n_poses, 3, 3), np.nan)
    pose_covs[0] = np.diag(np.square(INITIAL_STD))  # the fixed start: the filters' initial belief
    cpu = time.process_time() - c0
    times = t_start + np.array([0.0] + [s.time for s in steps])[dg.ticks]
    ids = np.asarray(solved.landmark_ids, dtype=np.int64)
    flt = GraphSlamMap(ids, solved.landmarks.copy(), mark_covs, report, dg.graph.poses.copy(),
                       dg.graph.first_landmark_pose())
    track = MrclamTrack(GRAPH_NAME, flt, times, solved.poses.copy(), pose_covs,
                        us_per_step=1e6 * cpu / max(len(steps), 1))
    history = MapHistory([float(times[-1])], [flt.landmarks()])
    return track, history


__all__ = ["COMMAND_DELAY_S", "GRAPH_CHUNK", "GRAPH_MAX_GAP", "GRAPH_NAME", "GraphSlamMap", "delayed",
           "graph_slam_track", "recorded_steps"]
