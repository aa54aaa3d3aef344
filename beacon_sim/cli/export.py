"""``beacon-sim export FILE --out run.npz|run.csv|run.mcap [--ros2]``: a recording, or a
headless run of a scenario, as arrays (with every filter's estimates), as an MCAP file for
Foxglove, or (``--ros2``, ``run.mcap`` or ``run.db3``) as a ROS 2 bag folder ``run/``."""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from beacon_sim.cli.common import check_duration, check_set_names, filter_params, print_failures
from beacon_sim.cli.replay import load
from beacon_sim.core.scenario import load_scenario
from beacon_sim.errors import UsageError
from beacon_sim.evaluation.pcrb import pcrb
from beacon_sim.io.export import filter_arrays, step_arrays, trace_arrays, write_export
from beacon_sim.io.foxglove import BeliefFrame, read_frame
from beacon_sim.runs.headless import run_headless
from beacon_sim.runs.replay import ReplayMismatch, recorded_filter_specs, replay_recording, skipped_note

SUFFIXES = (".npz", ".csv", ".mcap")
ROS2_SUFFIXES = (".mcap", ".db3")


def is_recording(file: str) -> bool:
    """A recording is an existing file that is not a scenario (``.toml``); anything else is
    a scenario name or path."""
    p = Path(file)
    return p.is_file() and p.suffix != ".toml"


class FrameKeeper:
    """Keeps each tick's :class:`BeliefFrame` (particles, grid beliefs, SLAM maps) while a run
    goes, for the MCAP export: an ``on_tick`` of ``run_headless`` / ``replay_recording``."""

    def __init__(self) -> None:
        self.frames: dict[int, BeliefFrame] = {}

    def __call__(self, step, runner) -> None:
        self.frames[step.tick] = read_frame(runner.members[0].tracks)

    def with_bound(self, scenario, arrays) -> dict[int, BeliefFrame]:
        """The frames with the PCRB of the run's true path (:func:`beacon_sim.evaluation.pcrb.pcrb`)."""
        bound = pcrb(scenario, arrays["truth"][None], arrays["control"][None])[0]
        return {k: replace(f, bound=bound[k - 1]) for k, f in self.frames.items() if 1 <= k <= len(bound)}


def export_command(args: argparse.Namespace) -> int:
    out = Path(args.out)
    ros2 = bool(getattr(args, "ros2", False))
    if ros2 and out.suffix not in ROS2_SUFFIXES:
        raise UsageError(f"--out {out}: with --ros2, expected run.mcap or run.db3 (the bag's storage)")
    if out.suffix not in SUFFIXES + ROS2_SUFFIXES or (out.suffix == ".db3" and not ros2):
        raise UsageError(f"--out {out}: expected a .npz, .csv or .mcap file name (.db3 with --ros2)")
    if ros2 and out.with_suffix("").exists() and not (out.with_suffix("") / "metadata.yaml").is_file():
        raise UsageError(f"--out {out}: {out.with_suffix('')} exists and is not a ROS 2 bag folder")
    if not out.parent.is_dir():
        raise UsageError(f"--out {out}: no such folder {out.parent}")
    check_duration(args.duration)
    keeper = FrameKeeper() if out.suffix == ".mcap" and not ros2 else None
    if is_recording(args.file):
        if args.seed is not None or args.duration is not None:
            raise UsageError("--seed and --duration are for a scenario; a recording has its own")
        recording = load(args.file)
        if recording.is_team:
            raise UsageError(f"{args.file}: a team recording: export takes a single-robot "
                             "recording or a scenario")
        check_set_names(args, recorded_filter_specs(recording, args.filters)[0])
        try:
            result = replay_recording(recording, args.filters, filter_params(args), on_tick=keeper)
        except ReplayMismatch as exc:
            raise UsageError(str(exc)) from None
        for spec in result.extra["replay"]["skipped_filters"]:
            print(skipped_note(spec), file=sys.stderr)
        arrays = trace_arrays(recording, result.steps, result.runner.tracks)
    else:
        scenario = load_scenario(args.file)
        check_duration(args.duration, scenario)
        check_set_names(args, list(args.filters or scenario.default_filters))
        result = run_headless(scenario, args.filters, seed=args.seed, duration=args.duration,
                              params=filter_params(args), on_tick=keeper)
        arrays = step_arrays(scenario, result.steps)
        arrays.update(filter_arrays(result.runner.tracks, len(result.steps)))
    print_failures(result.runner.tracks.values())
    if ros2:
        try:
            from beacon_sim.io.ros2 import write_ros2_bag
            written = [write_ros2_bag(out, result.scenario, arrays,
                                      {"seed": str(result.seed), "truth_checksum": result.truth_checksum})]
        except ImportError as exc:
            raise UsageError(str(exc)) from None
    elif out.suffix == ".mcap":
        try:
            from beacon_sim.io.mcap import layout_path, write_mcap
            assert keeper is not None
            written = [write_mcap(out, result.scenario, arrays,
                                  {"seed": str(result.seed), "truth_checksum": result.truth_checksum},
                                  keeper.with_bound(result.scenario, arrays)), layout_path(out)]
        except ImportError as exc:
            raise UsageError(str(exc)) from None
    else:
        written = write_export(arrays, out)
    print(f"exported {len(arrays['control'])} ticks, {len(arrays['readings_tick'])} readings, "
          f"{len(arrays['events_tick'])} events, {len(arrays['filter_names'])} filters "
          f"to {', '.join(map(str, written))}")
    return 0
