"""Real robot data: robots of a UTIAS MRCLAM data set run through any filter, one robot or
several at once (a single robot is a team of one): :func:`run_mrclam`, the one entry point.

- The noise the filters are told comes from the data (calibration.py); by default from the
  data set's other robots, never the scored one (held_out.py).
- Every filter runs through :class:`~beacon_sim.hosting.team_runner.TeamRunner` over the
  robots of a team scenario (scenario.py, runners.py). One robot: odometry and measurements
  interleaved by time stamp (seed 001 section III.C), the filters predicting with the latest
  command up to each reading's time. Several: one common clock, each robot's own filter
  (``independent``) against the team filters that also use the robots' sightings of each
  other (feeding.py).
- The modes (readings without IDs, SLAM without the map, maps kept for the window) are one
  :class:`~beacon_sim.runs.mrclam.options.MrclamOptions`; what comes back is a
  :class:`~beacon_sim.runs.mrclam.results.MrclamRun`, shown in the window by playback.py.

Reading the files: beacon_sim/io/mrclam.py. Frames and units: metres, radians, world frame
of the data set (Vicon), bearings relative to the heading and wrapped to [-pi, pi).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from beacon_sim.io.mrclam import MrclamData, MrclamError
from beacon_sim.runs.mrclam.calibration import Calibration
from beacon_sim.runs.mrclam.held_out import calibration_for
from beacon_sim.runs.mrclam.options import MrclamOptions
from beacon_sim.runs.mrclam.results import MrclamRun
from beacon_sim.runs.mrclam.runners import run_calibrated, run_span


def run_mrclam(data: MrclamData | Sequence[MrclamData], filters: list[str] | None = None,
               duration: float | None = None, params: dict[str, dict[str, Any]] | None = None,
               calibration: Calibration | str | None = "others", dt: float | None = None,
               unknown_ids: bool = False, slam: bool = False, record_maps: bool = False,
               progress: bool = False, graph: bool = False) -> MrclamRun:
    """Run filters over one robot's data, or over several robots of a data set at once.

    Every filter runs through :class:`~beacon_sim.hosting.team_runner.TeamRunner` (one
    robot is a team of one, scenario.py's ``mrclam_team``), starting at the ground truth of
    the first common odometry time (``INITIAL_STD``). One robot (``dt`` None): its odometry
    and readings interleaved by time stamp (feeding.py's ``feed_by_time_stamps``);
    single-robot filter specs. Several robots (or ``dt`` given): one clock of ``dt`` (default
    ``TEAM_DT``) [s] (``feed_on_a_clock``); team filter specs (``independent:F``,
    ``centralised``, ...; their sightings need the data loaded with ``robot_sightings=True``).

    ``calibration``: ``"others"`` (each robot's noise from the other robots of its folder,
    the default; the Gaussian filters' inflation, measured on the single-robot EKF, only
    for one robot: a team run is told the ``"pooled"`` noise), ``"pooled"``, ``"self"``
    (fitted on its own ground truth, labelled), or a :class:`Calibration` for every robot.
    Built-in filters get ``MRCLAM_PARAMS`` (the EKF's
    and UKF's chi-square gate, the particle filter's settings: the robots' scenario
    ``[filters.*]``) unless ``params`` set them; the particle and grid filters weigh
    readings with the calibrated outlier mixture (docs/replay.md).

    ``unknown_ids`` (one robot, interleaved by time stamp): the camera declares
    ``correspondence = "unknown"`` and every reading reaches the filters without its barcode
    (``UNKNOWN_ID``, rows shuffled), so they associate; the barcodes only score that
    (``MrclamRun.associations``). The noise is calibrated as without it (from ground truth and
    the barcodes of the other robots, or the run's own for ``"self"``).

    ``slam`` (one robot, interleaved by time stamp): every SLAM filter (a filter
    with ``landmarks()``) is built on a scenario whose map is withheld (``map_known`` False, no
    anchors: it maps the 15 landmarks itself from the known start); every other filter keeps
    the surveyed map, as the reference (map_history.py's ``map_withheld``). Default
    filters ``SLAM_MRCLAM_FILTERS``. With ``unknown_ids`` too, the readings also come without barcodes.
    ``record_maps`` (one robot): keep every SLAM filter's map after each update
    (``MrclamRun.map_history``), for the window.

    ``graph`` (with ``slam``, one robot, barcodes): graph SLAM over the same steps, solved
    after the run (runs/mrclam/graph_slam.py), is one more track, ``graph_slam``, scored
    beside the SLAM filters.

    ``progress``: the seconds of data fed so far on stderr, as ``run``'s progress (a bar on a
    terminal, a plain line every few seconds in a log file); the results are the same with or
    without it.
    """
    robots = [data] if isinstance(data, MrclamData) else list(data)
    if not robots:
        raise MrclamError("run_mrclam: no robot to run")
    options = MrclamOptions(dt, unknown_ids, slam, record_maps, graph)
    options.check(len(robots))
    t_start, t_end = run_span(robots, duration)
    return run_calibrated(robots, _calibrations(robots, calibration, t_end), filters, t_start, t_end,
                          params, options, progress)


def _calibrations(robots: list[MrclamData], calibration: Calibration | str | None,
                  t_end: float) -> list[Calibration]:
    """Each robot's noise as ``calibration`` asks (:func:`run_mrclam`); a team run is told
    the ``"pooled"`` noise for ``"others"``: the inflation is the single-robot EKF's
    (interleaved by time stamp)."""
    how = "self" if calibration is None else calibration
    if how == "others" and len(robots) > 1:
        how = "pooled"
    return [how if isinstance(how, Calibration) else calibration_for(d, how, t_end) for d in robots]
