"""What several commands share: the argument parser's one-line errors, the filter options,
and the notes printed on stderr."""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
from pathlib import Path
from typing import Any, NoReturn

from beacon_sim.core import arguments
from beacon_sim.core.scenario import MAX_TICKS, Scenario
from beacon_sim.errors import UsageError
from beacon_sim.hosting.loading import FilterLoadError, check_param_names, parse_set_options, sensor_note


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


def check_set_names(args: argparse.Namespace, specs: list[str]) -> None:
    """``--set NAME.KEY=VALUE``: NAME must be one of the filters that run."""
    check_param_names(filter_params(args), list(specs))


def check_duration(duration: float | None, scenario: Scenario | None = None) -> None:
    """``--duration S``: a positive, finite number of seconds (or absent); with a scenario,
    at least one tick of its ``dt`` and at most ``MAX_TICKS`` ticks."""
    # the same check as the Python API's duration= (core/arguments.py)
    arguments.check_duration(duration, None if scenario is None else scenario.dt, MAX_TICKS, "--duration")


def _probe_dir(option: str, path: str, folder: Path) -> None:
    """Create and remove a temporary file in ``folder`` (what a write needs), or one line."""
    try:
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as exc:
        raise UsageError(f"{option} {path}: cannot write in {folder}: {exc.strerror or exc}") from None


def _writable_file(option: str, path: str, create_parent: bool = False) -> None:
    p = Path(path)
    parent = p.parent if str(p.parent) else Path(".")
    if p.is_dir():
        raise UsageError(f"{option} {path}: is a folder, expected a file name")
    if create_parent and not parent.exists():
        _writable_dir(option, str(parent))
        return
    if not parent.is_dir():
        raise UsageError(f"{option} {path}: no such folder {parent}")
    if p.exists() and not os.access(p, os.W_OK):
        raise UsageError(f"{option} {path}: cannot write that file (permission denied)")
    _probe_dir(option, path, parent)


def _writable_dir(option: str, path: str) -> None:
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise UsageError(f"{option} {path}: exists and is not a folder")
    parent = next((q for q in [p.absolute(), *p.absolute().parents] if q.exists()), Path("/"))
    if not parent.is_dir():
        raise UsageError(f"{option} {path}: cannot create a folder under {parent}")
    _probe_dir(option, path, parent)


def check_common(args: argparse.Namespace) -> None:
    """The options several commands share, checked before anything runs: seeds, counts,
    times and output paths (one line, exit status 2, for each mistake)."""
    arguments.check_seed(getattr(args, "seed", None), "--seed")  # as the API's seed=
    check_duration(getattr(args, "duration", None))
    check_frames(getattr(args, "frames", None))
    for option in ("runs", "jobs", "robot"):
        n = getattr(args, option, None)
        if n is not None and not 1 <= n <= 1_000_000:
            raise UsageError(f"--{option} {n}: expected a whole number from 1 to 1000000")
    for option in ("time_limit", "start", "end", "speed"):
        x = getattr(args, option, None)
        if x is not None and not math.isfinite(x):
            raise UsageError(f"--{option.replace('_', '-')} {x}: expected a finite number")
    if args.command == "export":
        _writable_file("--out", args.out)
    elif getattr(args, "out", None) is not None:
        _writable_dir("--out", args.out)
    for option in ("screenshot", "gif"):
        if getattr(args, option, None) is not None:
            _writable_file(f"--{option}", getattr(args, option), create_parent=option == "screenshot")


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
    """A failed filter's reason and traceback on stderr (the table says FAILED); no
    traceback for a ``FilterError``, whose one line says it all (a localization filter
    given a reading of a beacon not on its map)."""
    for track in tracks:
        if track.failed:
            tb = None if str(track.failed).startswith("FilterError:") else getattr(track, "traceback", None)
            print(f"filter {track.name} failed: {track.failed}" + (f"\n{tb}" if tb else ""),
                  file=sys.stderr)
