"""``beacon-sim replay FILE [--filter F ...] [--headless] [--json]``: a recording replayed bit
for bit, on screen (with a timeline) or headless."""

from __future__ import annotations

import argparse
import json
import os
import sys

from beacon_sim.cli.common import check_frames, check_set_names, filter_params, print_failures
from beacon_sim.cli.play import check_gif
from beacon_sim.cli.tables import print_run
from beacon_sim.errors import UsageError
from beacon_sim.io.recording import Recording, RecordingError, load_recording
from beacon_sim.runs.replay import (
    ReplayMismatch,
    recorded_filter_specs,
    recorded_params,
    replay_recording,
    skipped_note,
)


def load(path: str) -> Recording:
    """The recording, its warnings printed; a bad file is a usage error (one line)."""
    try:
        recording = load_recording(path)
    except RecordingError as exc:
        raise UsageError(str(exc)) from None
    for note in recording.warnings:
        print(f"warning: {note}", file=sys.stderr)
    return recording


def check_span(start: float | None, end: float | None, duration: float) -> None:
    """``--start S --end S`` [s]: within the recording, start before end."""
    if start is not None and not 0.0 <= start < duration:
        raise UsageError(f"--start {start:g}: expected 0 <= S < {duration:g} (the recording's length)")
    if end is not None and not end > (start or 0.0):
        raise UsageError(f"--end {end:g}: expected a time after --start ({start or 0.0:g} s)")


def replay_command(args: argparse.Namespace) -> int:
    recording = load(args.file)
    params = filter_params(args)
    check_set_names(args, recorded_filter_specs(recording, args.filters or None)[0])
    if not args.headless:
        check_frames(args.frames)
        specs, skipped = recorded_filter_specs(recording, args.filters or None)
        for spec in skipped:
            print(skipped_note(spec), file=sys.stderr)
        check_gif(args.gif)
        check_span(args.start, args.end, len(recording.ticks) * recording.scenario.dt)
        if args.gif:  # a GIF is made off screen, as fast as it draws
            os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
        from beacon_sim.app.replay import show_replay  # pygame only when a window opens

        return show_replay(recording, specs, recorded_params(recording, params),
                           args.frames, args.screenshot, paused=args.paused, gif=args.gif,
                           start=args.start, end=args.end)
    try:
        result = replay_recording(recording, args.filters, params)
    except ReplayMismatch as exc:
        raise UsageError(str(exc)) from None
    info = result.extra["replay"]
    for spec in info["skipped_filters"]:
        print(skipped_note(spec), file=sys.stderr)
    data = result.as_json()
    data["replay"] = info
    if args.json:
        print(json.dumps(data, default=float))
    else:
        print(f"replay {info['file']}: {info['ticks']} ticks, truth checksum "
              f"{result.truth_checksum} {info['checksum_status']}")
        print_run(data)
    print_failures(result.runner.tracks.values())
    return 0
