"""Grading a class (``beacon-sim grade DIR``, docs/grading.md): every student's filter file
over the same scenarios and seeds, one row per student, a CSV and a self-contained HTML
leaderboard.

The sweep is a list of independent tasks (student, scenario, seed), each a
:func:`~beacon_sim.evaluation.montecarlo.one_run` with a per-run time limit, so it runs the
same on local processes (default) and on a Dask distributed cluster (``scheduler``): a
run's numbers depend only on its seed, never on where it ran (only the cost figures, wall
time, differ). A task that cannot run (the file does not import, a worker died of memory)
is a failed run, not a failed sweep. A student whose filter failed in any run gets no
score and is ranked below every working filter.

A team scenario (``[[robots]]``, docs/multi-robot.md) among the scenarios grades the
student's single-robot filter as every robot's own filter (``independent:FILTER``, the
team baseline: beacon readings only), beside the built-in independent EKF on the same
seeds (the ``reference``): the row's figures for it are the team's (RMSE over all robots,
mean ANEES, RMSE over each robot's bound alone), and ``team`` holds each robot's.

A SLAM scenario (the beacon map withheld) adds the map columns (the path's ATE, the final
map's GOSPA, the joint NEES) beside the built-in EKF-SLAM; a map world with a range finder
puts each row beside the built-in mcl (docs/grading.md, "A SLAM assignment", "A scan-based
assignment").

The package, one module per idea: ``config`` (what is graded, ``grade.toml``), ``roster``
(the class's files), ``tasks`` (runs in the grader's processes: the references),
``students`` (each student's filter in its child), ``secret``, ``cache``, ``scoring`` (runs
to rows, ranks), ``board`` (``grade()`` and its :class:`GradeResult`), ``csv_table``,
``html_pages``, ``svg``, ``outputs`` (what a grade writes); Dask is
:mod:`beacon_sim.evaluation.cluster`. The names below are its public API.
"""

from beacon_sim.evaluation.grading.board import GradeResult, grade
from beacon_sim.evaluation.grading.config import GradeConfig, GradeError, load_config, scenario_labels
from beacon_sim.evaluation.grading.csv_table import CSV_COLUMNS, write_csv
from beacon_sim.evaluation.grading.html_pages import pseudonym, write_html, write_student_page
from beacon_sim.evaluation.grading.outputs import write_outputs
from beacon_sim.evaluation.grading.roster import Student, find_class, find_students
from beacon_sim.evaluation.grading.scoring import is_scan_scenario, is_slam_scenario, rank_key, status
from beacon_sim.evaluation.grading.secret import (
    SECRET_FILE,
    check_secret,
    new_secret,
    read_secret,
    secret_fingerprint,
    write_secret,
)
from beacon_sim.evaluation.grading.students import (
    LOG_BYTES,
    PROBE_TICKS,
    StudentJob,
    StudentResult,
    TeamSimulated,
    run_student,
    run_students,
    simulate_team_run,
)
from beacon_sim.evaluation.grading.tasks import Task, TaskResult, run_task, run_tasks

__all__ = ["CSV_COLUMNS", "LOG_BYTES", "PROBE_TICKS", "SECRET_FILE", "GradeConfig", "GradeError",
           "GradeResult", "Student", "StudentJob", "StudentResult", "Task", "TaskResult", "TeamSimulated",
           "check_secret", "find_class", "find_students", "grade", "is_scan_scenario", "is_slam_scenario",
           "load_config", "new_secret", "pseudonym", "rank_key", "read_secret", "run_student", "run_students",
           "run_task", "run_tasks", "scenario_labels", "secret_fingerprint", "simulate_team_run", "status",
           "write_csv", "write_html", "write_outputs", "write_secret", "write_student_page"]
