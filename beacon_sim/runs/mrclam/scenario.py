"""What the filters of a MRCLAM run may know, as a scenario: the landmark map, the calibrated
noise and the initial belief of each robot (:func:`mrclam_scenario`), and the robots of a run
as a team (:func:`mrclam_team`; a single robot is a team of one). Metres, radians, the data
set's world frame."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from beacon_sim.core.drivers import KeyboardSpec
from beacon_sim.core.keyboard_drive import KeyboardLimits
from beacon_sim.core.scenario import (
    InitialBelief,
    RobotSensorSpec,
    Scenario,
    TeamRobot,
    TeamScenario,
    team_of_one,
)
from beacon_sim.core.sensors import SensorSpec
from beacon_sim.core.types import Beacon
from beacon_sim.core.world import World
from beacon_sim.filters.registry import MRCLAM_DEFAULTS
from beacon_sim.filters.registry import MRCLAM_GATE_CHI2 as MRCLAM_GATE_CHI2  # re-exported
from beacon_sim.filters.team import TEAM_FILTERS
from beacon_sim.io.mrclam import ROBOT_SUBJECTS, MrclamData, MrclamError
from beacon_sim.runs.mrclam.calibration import Calibration

#: The landmark camera's sensor name in a MRCLAM scenario.
SENSOR_NAME = "camera"
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


def mrclam_scenario(data: MrclamData, cal: Calibration, t_start: float, t_end: float,
                    correspondence: str = "known", map_known: bool = True) -> Scenario:
    """A :class:`Scenario` holding what the filters may know: the landmark map, the
    calibrated motion and sensor noise, and the initial belief (ground truth at the start).
    ``correspondence="unknown"`` (``--unknown-ids``): the camera's readings carry no
    landmark IDs and the filters associate them with the map themselves. ``map_known=False``
    (``--slam``): the surveyed landmarks stay in ``world`` (for scoring) but the
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
