"""Real robot data: robots of a UTIAS MRCLAM data set run through any filter, one robot or
several at once (:func:`run_mrclam`; docs/replay.md, docs/multi-robot.md).

The modules of this package are private; the names below are its public import path
(``from beacon_sim.runs.mrclam import run_mrclam``):

- calibration.py: the noise the filters are told, estimated from the data
- held_out.py: the noise from the data set's other robots, inflated on held-out runs
- scenario.py: the robots of a run as a scenario / team scenario
- options.py: the run's modes (readings without IDs, SLAM, maps kept) as one record
- feeding.py: odometry and readings fed to the runners, by time stamp or on a clock
- associations.py: scoring the associations of readings given without IDs
- map_history.py: the SLAM filters' maps, withheld and recorded
- runners.py: the runners built, fed and their tracks collected
- results.py: the run's tracks, scores and JSON
- run.py: :func:`run_mrclam`, the entry point
- playback.py: a finished run shown one display tick at a time, for the window
"""

from beacon_sim.runs.mrclam.associations import AssociationCount
from beacon_sim.runs.mrclam.calibration import (
    CALIBRATION_WINDOW_S,
    COMMAND_SCALE_RANGE,
    DATASET_ROBOTS,
    MIN_OUTLIER_RATE,
    SUB_S,
    Calibration,
    calibrate,
    command_scale,
    inflated,
    other_runs,
    pooled_calibration,
    rms,
    robust_std,
    shared_error_factor,
    told_inflated,
)
from beacon_sim.runs.mrclam.feeding import UNKNOWN_IDS_SHUFFLE_SEED
from beacon_sim.runs.mrclam.held_out import (
    CALIBRATIONS,
    INFLATION_QUANTILE,
    calibration_for,
    held_out_inflation,
    leave_one_robot_out,
)
from beacon_sim.runs.mrclam.map_history import SLAM_MRCLAM_FILTERS, MapHistory, map_withheld
from beacon_sim.runs.mrclam.options import MrclamOptions
from beacon_sim.runs.mrclam.playback import READING_SHOW_S, MrclamPlayback
from beacon_sim.runs.mrclam.results import (
    SEED_001_EKF_MSE,
    SEED_001_UKF_MSE,
    MrclamRun,
    MrclamTrack,
    nees_or_inf,
)
from beacon_sim.runs.mrclam.run import run_mrclam
from beacon_sim.runs.mrclam.scenario import (
    INITIAL_STD,
    MRCLAM_GATE_CHI2,
    MRCLAM_PARAMS,
    SENSOR_NAME,
    SIGHTING_SENSOR,
    TEAM_DT,
    TEAM_MRCLAM_FILTERS,
    mrclam_scenario,
    mrclam_team,
)

__all__ = [
    "CALIBRATIONS", "CALIBRATION_WINDOW_S", "COMMAND_SCALE_RANGE", "DATASET_ROBOTS", "INFLATION_QUANTILE",
    "INITIAL_STD", "MIN_OUTLIER_RATE", "MRCLAM_GATE_CHI2", "MRCLAM_PARAMS", "READING_SHOW_S",
    "SEED_001_EKF_MSE", "SEED_001_UKF_MSE", "SENSOR_NAME", "SIGHTING_SENSOR", "SLAM_MRCLAM_FILTERS",
    "SUB_S", "TEAM_DT", "TEAM_MRCLAM_FILTERS", "UNKNOWN_IDS_SHUFFLE_SEED", "AssociationCount",
    "Calibration", "MapHistory", "MrclamOptions", "MrclamPlayback", "MrclamRun", "MrclamTrack", "calibrate",
    "calibration_for", "command_scale", "held_out_inflation", "inflated", "leave_one_robot_out",
    "map_withheld", "mrclam_scenario", "mrclam_team", "nees_or_inf", "other_runs",
    "pooled_calibration", "rms", "robust_std", "run_mrclam", "shared_error_factor", "told_inflated",
]
