"""``beacon-sim export FILE --out trace.npz|trace.csv``: a recording as arrays."""

from __future__ import annotations

import argparse
from pathlib import Path

from beacon_sim.cli.replay import load
from beacon_sim.errors import UsageError
from beacon_sim.io.export import trace_arrays, write_export
from beacon_sim.runs.replay import ReplayMismatch, replay_recording


def export_command(args: argparse.Namespace) -> int:
    out = Path(args.out)
    if out.suffix not in (".npz", ".csv"):
        raise UsageError(f"--out {out}: expected a .npz or .csv file name")
    if not out.parent.is_dir():
        raise UsageError(f"--out {out}: no such folder {out.parent}")
    recording = load(args.file)
    try:
        steps = replay_recording(recording, filters=[]).steps
    except ReplayMismatch as exc:
        raise UsageError(str(exc)) from None
    arrays = trace_arrays(recording, steps)
    written = write_export(arrays, out)
    print(f"exported {len(arrays['control'])} ticks, {len(arrays['meas_tick'])} readings, "
          f"{len(arrays['event_tick'])} events to {', '.join(map(str, written))}")
    return 0
