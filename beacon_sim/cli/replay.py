"""``beacon-sim replay FILE [--filter F ...] [--headless] [--json]``: a recording replayed bit
for bit, on screen (with a timeline) or headless. A team session's recording replays its
team (``--filter`` names team filters, as ``run`` on a team scenario)."""

from __future__ import annotations

import argparse
import json
import os
import sys

from beacon_sim.cli.common import check_frames, check_set_names, filter_params, print_failures
from beacon_sim.cli.play import check_foxglove, check_gif, parse_gif_width, parse_size
from beacon_sim.cli.run import print_team_run
from beacon_sim.cli.tables import print_run
from beacon_sim.errors import UsageError
from beacon_sim.io.recording import Recording, RecordingError, TeamRecording, load_any_recording
from beacon_sim.runs.replay import (
    ReplayMismatch,
    recorded_filter_specs,
    recorded_params,
    replay_recording,
    skipped_note,
)


def load(path: str) -> Recording | TeamRecording:
    """The recording (single-robot or team), its warnings printed; a bad file is a usage
    error (one line)."""
    try:
        recording = load_any_recording(path)
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
    if isinstance(recording, TeamRecording):
        return replay_team_command(args, recording)
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
                           start=args.start, end=args.end, size=parse_size(args.size),
                           gif_width=parse_gif_width(args.gif_width), foxglove=check_foxglove(args))
    if getattr(args, "foxglove", None) is not None:
        raise UsageError("--foxglove streams the replay window: drop --headless")
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


def replay_team_command(args: argparse.Namespace, recording: TeamRecording) -> int:
    """``replay`` of a team session's recording: the recorded built-in team filters (or the
    ``--filter`` ones) on the re-simulated team, checked against the file's checksums; the
    figures of ``run`` on a team scenario."""
    from beacon_sim.filters.team_specs import check_team_specs, team_filter_name
    from beacon_sim.runs.team_replay import recorded_team_specs, replay_team_recording

    if getattr(args, "foxglove", None) is not None:
        raise UsageError("--foxglove: not for team recordings yet (one robot only)")
    params = filter_params(args)
    specs, skipped = recorded_team_specs(recording, args.filters or None)
    merged = recorded_params(recording, params)
    running = {team_filter_name(s) for s in specs}
    # a bad name, --set or recorded parameter: one line, exit 2, before anything runs (as run)
    check_team_specs(specs, recording.team,
                     {n: p for n, p in merged.items() if n in running or n in params})
    for spec in skipped:
        print(skipped_note(spec), file=sys.stderr)
    if not args.headless:
        check_frames(args.frames)
        check_gif(args.gif)
        check_span(args.start, args.end, len(recording.ticks) * recording.team.dt)
        if args.gif:
            os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
        from beacon_sim.app.replay import show_replay  # pygame only when a window opens

        return show_replay(recording, specs, merged, args.frames, args.screenshot,
                           paused=args.paused, gif=args.gif, start=args.start, end=args.end,
                           size=parse_size(args.size), gif_width=parse_gif_width(args.gif_width))
    try:
        out = replay_team_recording(recording, specs, merged)
    except ReplayMismatch as exc:
        raise UsageError(str(exc)) from None
    info = out.replay
    data = out.as_json()
    if args.json:
        print(json.dumps(data, default=float))
    else:
        print(f"replay {info['file']}: {info['ticks']} ticks, truth checksum "
              f"{out.result.truth_checksum} {info['checksum_status']}")
        print_team_run(data)
    print_failures(out.result.tracks.values())
    return 0
