"""The ``beacon-sim`` command line: the parser, and one module per subcommand beside this one.

Only this package reads argparse results; each subcommand checks its arguments and calls
typed library functions. Bad arguments or files give a one-line message, exit status 2
and no traceback.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
import warnings
from collections.abc import Callable

from beacon_sim.cli import autograde, check, export, graph, listing, mrclam, new_filter, play, replay, run
from beacon_sim.cli import eval as eval_cli
from beacon_sim.cli import grade as grade_cli
from beacon_sim.cli.common import Parser, add_filter_options, check_common
from beacon_sim.core.threads import limit_blas_threads
from beacon_sim.errors import BeaconSimError, FileReplacedWarning, UsageError
from beacon_sim.hosting.runner import note_user_interrupt
from beacon_sim.version import __version__


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="beacon-sim", description="Drive a robot among beacons and watch "
                     "Bayesian filters localise it. With no command: play the default scenario.")
    parser.add_argument("--version", action="version", version=f"beacon-sim {__version__}")
    sub = parser.add_subparsers(dest="command", parser_class=Parser)

    p = sub.add_parser("play", help="open the simulator window")
    p.add_argument("scenario", nargs="?", default="default",
                   help="a shipped scenario's name (beacon-sim list) or a .toml file (default: default)")
    add_filter_options(p)
    p.add_argument("--seed", type=int, metavar="N",
                   help="the run's seed, 0 to 2^63 - 1 (default: the scenario's)")
    p.add_argument("--no-record", action="store_true", help="do not record this session")
    p.add_argument("--frames", type=int, help="quit after N frames (for scripts and tests)")
    p.add_argument("--screenshot", metavar="PNG", help="save the last frame to PNG")
    p.add_argument("--size", default="1280x800", help="window size WxH in pixels")
    p.add_argument("--autopilot", action="store_true",
                   help="start with the scenario's driver at the wheel (M toggles it)")
    p.add_argument("--paused", action="store_true", help="start paused (Space runs, . steps one tick)")
    p.add_argument("--speed", type=float, metavar="X", help="start at this speed factor (0.1 to 8)")
    p.add_argument("--gif", metavar="GIF", help="also write the session as an animated GIF (Pillow)")
    p.add_argument("--gif-width", default="640", metavar="PX",
                   help="the GIF's width in pixels, or 'window' for the window's (default 640)")
    add_foxglove_option(p, "the session")

    p = sub.add_parser("run", help="one headless run; prints a summary")
    p.add_argument("scenario", help="a shipped scenario's name (beacon-sim list), a .toml file "
                                    "or a team scenario")
    add_filter_options(p)
    p.add_argument("--seed", type=int, metavar="N",
                   help="the run's seed, 0 to 2^63 - 1 (default: the scenario's)")
    p.add_argument("--duration", type=float, metavar="S", help="seconds to simulate")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--associations", action="store_true",
                   help="readings without IDs: also score each filter's associations and their "
                        "RMSE cost against a run with known IDs (docs/association.md)")
    p.add_argument("--smooth", action="store_true",
                   help="also smooth the EKF/UKF runs (Rauch-Tung-Striebel) and report filtered and "
                        "smoothed against the truth and the bounds (docs/smoothing.md)")

    p = sub.add_parser("check", help="conformance report for a filter")
    p.add_argument("filter", help="a built-in name, pkg.mod:Class, file.py:Class or a file of functions")
    p.add_argument("--scenario", default="default", help="the scenario to check it on (default: default)")
    p.add_argument("--sandbox", choices=("auto", "bwrap", "process", "none"),
                   help="a filter file runs in a process of its own (default auto; none: in "
                        "this process)")

    sub.add_parser("list", help="shipped scenarios and available filters")

    p = sub.add_parser("eval", help="Monte Carlo comparison of filters over seeds")
    p.add_argument("scenarios", nargs="+", metavar="SCENARIO",
                   help="one or more scenarios (names or .toml files), each evaluated in turn")
    add_filter_options(p)
    p.add_argument("--runs", type=int, default=20, metavar="N",
                   help="Monte Carlo runs per scenario, seeds SEED .. SEED + N - 1 (default 20)")
    p.add_argument("--seed", type=int, default=0, metavar="SEED", help="the first run's seed (default 0)")
    p.add_argument("--duration", type=float, metavar="S",
                   help="seconds to simulate per run (default: each scenario's duration)")
    p.add_argument("--jobs", type=int, help="parallel processes (default: all cores)")
    p.add_argument("--out", metavar="DIR", help="write CSV, JSON and PNG plots here")
    p.add_argument("--json", action="store_true", help="print the results as one JSON object")
    p.add_argument("--no-batch", action="store_true",
                   help="run the filters one run at a time (default: batched across runs when possible)")
    p.add_argument("--strict", action="store_true",
                   help="exit status 1 when any filter failed in any run")
    p.add_argument("--time-limit", type=float, metavar="S",
                   help="stop a filter whose steps take over S seconds in one run (default 300)")
    p.add_argument("--sandbox", choices=("auto", "bwrap", "process", "none"),
                   help="filter files run in a process of their own (default auto: bubblewrap "
                        "where it works; none: in this process; docs/grading.md)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run on a Dask cluster, e.g. tcp://host:8786 (the same results as local "
                        "--jobs; docs/evaluation.md)")
    p.add_argument("--smooth", action="store_true",
                   help="also smooth the EKF/UKF runs (Rauch-Tung-Striebel) over the same seeds: "
                        "RMSE and ANEES filtered and smoothed, against the filtering and smoothing "
                        "bounds, with intervals (docs/smoothing.md)")

    p = sub.add_parser("replay", help="replay a recording bit for bit, with any filters")
    p.add_argument("file", help="a recording (.jsonl) written by beacon-sim play")
    add_filter_options(p)
    p.add_argument("--headless", action="store_true", help="no window: replay and print the summary")
    p.add_argument("--json", action="store_true", help="with --headless: print one JSON object")
    p.add_argument("--frames", type=int, help="on screen: quit after N frames of 1/60 s")
    p.add_argument("--screenshot", metavar="PNG", help="on screen: save the last frame to PNG")
    p.add_argument("--paused", action="store_true", help="on screen: start paused")
    p.add_argument("--gif", metavar="GIF", help="write an animated GIF of the replay (off screen) and stop")
    p.add_argument("--start", type=float, metavar="S", help="start at S seconds (with --gif or on screen)")
    p.add_argument("--end", type=float, metavar="S", help="with --gif: stop at S seconds")
    p.add_argument("--size", default="1280x800", help="on screen: window size WxH in pixels")
    p.add_argument("--gif-width", default="640", metavar="PX",
                   help="the GIF's width in pixels, or 'window' for the window's (default 640)")
    p.add_argument("--smooth", action="store_true",
                   help="on screen: draw each EKF/UKF's smoothed trajectory and ellipse (RTS over the "
                        "whole recording) beside the filtered ones (docs/smoothing.md)")
    add_foxglove_option(p, "the replay window's session")

    p = sub.add_parser("export", help="a recording or a headless run as arrays (.npz, .csv), "
                                      "MCAP for Foxglove (.mcap) or a ROS 2 bag (--ros2)")
    p.add_argument("file", metavar="FILE", help="a recording (.jsonl) or a scenario (name or .toml)")
    p.add_argument("--out", required=True, metavar="PATH",
                   help="run.npz, run.csv or run.mcap; with --ros2 run.mcap or run.db3 (the bag folder run/)")
    p.add_argument("--ros2", action="store_true",
                   help="a ROS 2 bag (standard messages, frames map/odom/base_link; docs/replay.md) "
                        "in MCAP (.mcap) or SQLite 3 (.db3) storage; needs rosbags")
    add_filter_options(p)
    p.add_argument("--seed", type=int, help="a scenario's seed (default: the scenario's)")
    p.add_argument("--duration", type=float, metavar="S", help="a scenario: seconds to simulate")

    p = sub.add_parser("mrclam", help="replay a UTIAS MRCLAM data set folder")
    p.add_argument("dir", nargs="?", metavar="DIR",
                   help="the data set's folder (Robot1_Odometry.dat, Landmark_Groundtruth.dat, "
                        "...) or a folder holding Dataset6 (default: the environment variable "
                        "BEACON_SIM_MRCLAM; docs/mrclam.md)")
    p.add_argument("--robot", type=int, help="the robot, 1 to 5 (required without --team)")
    p.add_argument("--team", action="store_true",
                   help="all five robots at once, alone against cooperatively with their "
                        "sightings of each other (docs/multi-robot.md); headless")
    add_filter_options(p)
    p.add_argument("--headless", action="store_true", help="no window: run and print the summary")
    p.add_argument("--json", action="store_true", help="with --headless: print one JSON object")
    p.add_argument("--duration", type=float, metavar="S", help="only the first S seconds")
    p.add_argument("--calibrate", action="store_true",
                   help="print the noise settings estimated from the data and stop")
    p.add_argument("--calibration", choices=("others", "pooled", "self"), default="others",
                   help="where the filters' noise comes from: the data set's other robots "
                        "(default, leave-one-robot-out, the EKF/UKF variances inflated to the "
                        "other robots' consistency), the same without the inflation (pooled), "
                        "or the scored run's own ground truth (fitted on the answer)")
    p.add_argument("--unknown-ids", action="store_true",
                   help="give the filters the readings without their barcodes: they associate "
                        "them with the landmarks; the barcodes only score that (docs/association.md)")
    p.add_argument("--slam", action="store_true",
                   help="withhold the landmark map from the SLAM filters (default ekf_slam, "
                        "fastslam, and the EKF given the map); score their maps against the "
                        "surveyed landmarks (docs/slam.md)")
    p.add_argument("--graph", action="store_true",
                   help="with --slam: graph SLAM too, the whole run's odometry and readings "
                        "solved as one factor graph, scored beside the SLAM filters")
    p.add_argument("--frames", type=int, help="quit the window after N frames (for scripts and tests)")
    p.add_argument("--screenshot", metavar="PNG", help="save the window's last frame to PNG")
    p.add_argument("--size", default="1280x800", help="the window's size WxH in pixels")

    p = sub.add_parser("grade", help="grade a folder of filter files (one per student): "
                                     "CSV + HTML leaderboard")
    p.add_argument("dir", help="folder with one filter file per student")
    p.add_argument("--config", metavar="TOML",
                   help="scenarios, seeds, duration, time_limit (docs/grading.md)")
    p.add_argument("--out", metavar="DIR",
                   help="where grade.csv, grade.html, grade.json go (default DIR/grade_out)")
    p.add_argument("--jobs", type=int, help="students graded at once locally (default: cores + 1)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="run on a Dask cluster, e.g. tcp://host:8786")
    p.add_argument("--time-limit", type=float, metavar="S", help="a filter's time limit per run [s]")
    p.add_argument("--sandbox", choices=("auto", "bwrap", "process"),
                   help="how each student's process is contained (default auto: bubblewrap "
                        "where it works, else the process level; docs/grading.md)")
    p.add_argument("--no-cache", action="store_true",
                   help="run every student again (default: a student whose file and settings are "
                        "unchanged reuses OUT/cache)")
    p.add_argument("--allow-unisolated", action="store_true",
                   help="grade a class at the process level although the students' processes are "
                        "not isolated from each other (no bubblewrap); the page and the terminal "
                        "say what a file could do (docs/threat-model.md)")
    p.add_argument("--pseudonyms", action="store_true",
                   help="the class page names students by pseudonyms (pseudonyms.csv maps them)")
    secret = p.add_mutually_exclusive_group()
    secret.add_argument("--secret-file", metavar="FILE",
                        help="key the students' random streams with this grade's secret (the "
                             "grade.secret a grade wrote): a regrade, or one student graded alone, "
                             "gives the same figures bit for bit (default: OUT/grade.secret when "
                             "it exists, else a new secret)")
    secret.add_argument("--new-secret", action="store_true",
                        help="draw a new secret even when OUT/grade.secret exists")
    p.add_argument("--strict", action="store_true", help="exit status 1 when any filter failed")
    p.add_argument("--gradescope", metavar="DIR",
                   help="also write DIR/STUDENT/results.json, Gradescope's autograder output, "
                        "from the config's [[rubric]] (docs/grading.md)")

    p = sub.add_parser("autograde", help="grade one submission against a rubric and write "
                                         "Gradescope's results.json (a course's run_autograder)")
    p.add_argument("submission", help="the filter file, or a folder holding exactly one .py file")
    p.add_argument("--config", metavar="TOML", required=True,
                   help="the grade config with its [[rubric]] (docs/grading.md)")
    p.add_argument("--results", metavar="PATH",
                   help="where results.json goes (default /autograder/results/results.json)")
    p.add_argument("--secret-file", metavar="FILE",
                   help="key the filter's random streams with this grade's secret (a regrade "
                        "bit for bit; default a new secret)")

    graph.add_parser(sub)

    p = sub.add_parser("new-filter", help="write a working, commented filter template")
    p.add_argument("path", help="the .py file to write (refused if it exists)")
    p.add_argument("--team", action="store_true",
                   help="a team filter for scenarios with several robots (docs/multi-robot.md)")
    p.add_argument("--slam", action="store_true",
                   help="a SLAM filter that maps the beacons itself (docs/slam.md)")
    p.add_argument("--scan", action="store_true",
                   help="a particle filter on laser scans and an occupancy grid (docs/maps.md)")
    p.add_argument("--tdoa", action="store_true",
                   help="an EKF on range differences from ceiling beacons (docs/distance_beacons.md)")
    p.add_argument("--gauss-newton", action="store_true",
                   help="a graph SLAM solver's Gauss-Newton step, for `graph --solver` (docs/smoothing.md)")
    return parser


def add_foxglove_option(p: argparse.ArgumentParser, what: str) -> None:
    """``--foxglove [PORT]`` (default port 8765): stream live to Foxglove on 127.0.0.1."""
    p.add_argument("--foxglove", type=int, nargs="?", const=8765, metavar="PORT",
                   help=f"also stream {what} live to Foxglove: a WebSocket server on 127.0.0.1:PORT "
                        "(default 8765; 0 picks a free port; needs the mcap extra)")


COMMANDS: dict[str, Callable[[argparse.Namespace], int]] = {
    "run": run.run_command,
    "list": listing.list_command,
    "check": check.check_command,
    "play": play.play_command,
    "eval": eval_cli.eval_command,
    "replay": replay.replay_command,
    "export": export.export_command,
    "mrclam": mrclam.mrclam_command,
    "new-filter": new_filter.new_filter_command,
    "grade": grade_cli.grade_command,
    "autograde": autograde.autograde_command,
    "graph": graph.graph_command,
}


def _on_sigint(signum, frame) -> None:
    """The user's Ctrl-C: marked as the user's (the filter guard turns a KeyboardInterrupt
    raised by filter code into that filter's failure, never this one), then raised."""
    note_user_interrupt()
    raise KeyboardInterrupt


def _silence_stdout() -> None:
    """Point stdout at the null device, so the interpreter's final flush of what the closed
    pipe never took raises nothing at exit."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):  # no real file descriptor (a test's capture)
        pass


def _one_line_notes(showwarning: Callable[..., None]) -> Callable[..., None]:
    """``warnings.showwarning`` printing beacon-sim's own notes (a replaced file) as one
    line, ``beacon-sim: note: ...``; any other warning as ``showwarning`` does."""
    def show(message, category, filename, lineno, file=None, line=None) -> None:
        if isinstance(category, type) and issubclass(category, FileReplacedWarning):
            print(f"beacon-sim: note: {message}", file=sys.stderr)
        else:
            showwarning(message, category, filename, lineno, file, line)
    return show


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``beacon-sim`` console script; returns the exit status."""
    with warnings.catch_warnings():
        warnings.showwarning = _one_line_notes(warnings.showwarning)
        return _main(argv)


def _main(argv: list[str] | None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if threading.current_thread() is threading.main_thread() \
            and signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, _on_sigint)
    try:
        try:
            limit_blas_threads()   # one BLAS thread unless BEACON_SIM_BLAS_THREADS says otherwise
        except ValueError as exc:
            raise UsageError(f"beacon-sim: {exc}") from None
        parser = build_parser()
        args = parser.parse_args(argv or ["play"])
        if args.command is None:
            raise UsageError("beacon-sim: expected a command (see beacon-sim --help)")
        check_common(args)
        status = COMMANDS[args.command](args)
        sys.stdout.flush()  # a closed pipe shows here, inside the try, not at exit
        return status
    except BrokenPipeError:  # `beacon-sim list | head`: the reader left; quiet, as Unix tools
        _silence_stdout()
        return 128 + signal.SIGPIPE if hasattr(signal, "SIGPIPE") else 1
    except BeaconSimError as exc:  # ScenarioError, FilterError, RecordingError, UsageError, ...
        text = " ".join(str(exc).split()) or type(exc).__name__  # one line
        print(text if text.startswith("beacon-sim") else f"beacon-sim: {text}", file=sys.stderr)
        return 2
    except OSError as exc:  # a file or folder that cannot be read or written
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"beacon-sim: {where}{exc.strerror or exc}", file=sys.stderr)
        return 2
    except MemoryError:
        print("beacon-sim: out of memory (use a smaller scenario, grid or particle count)",
              file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    raise SystemExit(main())
