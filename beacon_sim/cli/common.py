"""What several commands share: the argument parser's one-line errors, the filter options,
and the notes printed on stderr."""

from __future__ import annotations

import argparse
import math
import sys
from typing import Any, NoReturn

from beacon_sim.core.scenario import Scenario
from beacon_sim.errors import UsageError
from beacon_sim.filters.loading import FilterLoadError, parse_set_options, sensor_note


class Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line and exit status 2 (no usage dump)."""

    def error(self, message: str) -> NoReturn:  # raises instead of exiting
        raise UsageError(f"{self.prog}: {message} (see {self.prog} --help)")


def add_filter_options(p: argparse.ArgumentParser) -> None:
    """``--filter F`` (repeatable) and ``--set NAME.KEY=VALUE``."""
    p.add_argument("--filter", action="append", metavar="F", dest="filters",
                   help="filter to run: built-in name, pkg.mod:Class or file.py:Class "
                        "(repeat for several; default: the scenario's default_filters)")
    p.add_argument("--set", action="append", default=[], metavar="NAME.KEY=VALUE",
                   dest="set_params", help="override a filter parameter, e.g. pf.n_particles=1000")


def filter_params(args: argparse.Namespace) -> dict[str, dict[str, Any]]:
    """The ``--set`` options as ``{filter name: {key: value}}``."""
    return parse_set_options(args.set_params)


def check_duration(duration: float | None) -> None:
    """``--duration S``: a positive, finite number of seconds (or absent)."""
    if duration is not None and not (duration > 0 and math.isfinite(duration)):
        raise UsageError(f"--duration {duration}: expected a positive number of seconds")


def check_frames(frames: int | None) -> None:
    """``--frames N``: a positive number of frames (or absent)."""
    if frames is not None and frames < 1:
        raise UsageError(f"--frames {frames}: expected a positive number of frames")


def print_sensor_notes(specs: list[str], scenario: Scenario) -> None:
    """Tell the user, on stderr, about filters that can use none of the scenario's sensors."""
    for spec in specs:
        try:
            note = sensor_note(spec, scenario)
        except FilterLoadError:
            continue
        if note:
            print(note, file=sys.stderr)


def print_failures(tracks) -> None:
    """A failed filter's reason and traceback on stderr (the table says FAILED)."""
    for track in tracks:
        if track.failed:
            tb = getattr(track, "traceback", None)
            print(f"filter {track.name} failed: {track.failed}" + (f"\n{tb}" if tb else ""),
                  file=sys.stderr)
