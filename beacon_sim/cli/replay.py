"""``beacon-sim replay FILE [--filter F ...] [--headless] [--json]``: a recording of any
number of robots replayed bit for bit, on screen (with a timeline) or headless. A team's
recording replays its team (``--filter`` names team filters, as ``run`` on a team scenario)."""

from __future__ import annotations

import argparse
import json
import os
import sys
from typing import Any

from beacon_sim.cli.common import check_frames, check_set_names, filter_params, print_failures
from beacon_sim.cli.play import check_foxglove, check_gif, parse_gif_width, parse_size
from beacon_sim.cli.run import print_team_run
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
    """The recording (of one robot or a team), its warnings printed; a bad file is a usage
    error (one line)."""
    try:
        recording = load_recording(path)
    except RecordingError as exc:
        raise UsageError(str(exc)) from None
    for note in recording.warnings:
        print(f"warning: {note}", file=sys.stderr)
    return recording


def check_filters(args: argparse.Namespace, recording: Recording, specs: list[str],
                  merged: dict[str, dict[str, Any]]) -> None:
    """A bad ``--set`` name (or, on a team, a bad team filter name or parameter, recorded
    ones included): one line, exit status 2, before anything runs (as ``run``)."""
    if not recording.is_team:
        check_set_names(args, specs)
        return
    from beacon_sim.hosting.team_specs import check_team_specs, team_filter_name

    params = filter_params(args)
    running = {team_filter_name(s) for s in specs}
    check_team_specs(specs, recording.team,
                     {n: p for n, p in merged.items() if n in running or n in params})


def check_span(start: float | None, end: float | None, duration: float) -> None:
    """``--start S --end S`` [s]: within the recording, start before end."""
    if start is not None and not 0.0 <= start < duration:
        raise UsageError(f"--start {start:g}: expected 0 <= S < {duration:g} (the recording's length)")
    if end is not None and not end > (start or 0.0):
        raise UsageError(f"--end {end:g}: expected a time after --start ({start or 0.0:g} s)")


def replay_command(args: argparse.Namespace) -> int:
    recording = load(args.file)
    params = filter_params(args)
    specs, skipped = recorded_filter_specs(recording, args.filters or None)
    merged = recorded_params(recording, params)
    check_filters(args, recording, specs, merged)
    if recording.is_team and getattr(args, "foxglove", None) is not None:
        raise UsageError("--foxglove: not for team recordings yet (one robot only)")
    for spec in skipped:
        print(skipped_note(spec), file=sys.stderr)
    if not args.headless:
        check_frames(args.frames)
        check_gif(args.gif)
        check_span(args.start, args.end, len(recording.ticks) * recording.team.dt)
        if args.gif:  # a GIF is made off screen, as fast as it draws
            os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
        from beacon_sim.app.replay import show_replay  # pygame only when a window opens

        smoothed = None
        if getattr(args, "smooth", False):  # the EKF/UKF of the recording, smoothed (docs/smoothing.md)
            from beacon_sim.runs.smoothing import NotSmoothable, smooth_recording

            try:
                smoothed = smooth_recording(recording, specs, merged)
            except (NotSmoothable, ReplayMismatch) as exc:
                raise UsageError(str(exc)) from None
            if not smoothed:
                print("note: --smooth: no filter of this replay can be smoothed (ekf, ukf)", file=sys.stderr)

        return show_replay(recording, specs, merged, args.frames, args.screenshot,
                           paused=args.paused, gif=args.gif, start=args.start, end=args.end,
                           size=parse_size(args.size), gif_width=parse_gif_width(args.gif_width),
                           foxglove=check_foxglove(args), smoothed=smoothed)
    if getattr(args, "foxglove", None) is not None:
        raise UsageError("--foxglove streams the replay window: drop --headless")
    if getattr(args, "smooth", False):
        raise UsageError("replay --smooth draws in the window: drop --headless (run --smooth prints "
                         "the figures)")
    try:
        out = replay_recording(recording, args.filters or None, params)
    except ReplayMismatch as exc:
        raise UsageError(f"not verified: {exc}") from None
    info, data = out.extra["replay"], out.as_json()
    data["replay"] = info
    if args.json:
        print(json.dumps(data, default=float))
    else:
        print(f"replay {info['file']}: {info['ticks']} ticks, truth checksum "
              f"{out.truth_checksum}: {info['checksum_status']}")
        (print_team_run if recording.is_team else print_run)(data)
    print_failures(out.tracks.values())
    return 0
