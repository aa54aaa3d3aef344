"""Replaying a recording bit for bit (with the recorded filters or any others), and exporting
it as arrays for a notebook.

``beacon-sim replay FILE [--filter F ...] [--set N.K=V] [--headless] [--json]`` and
``beacon-sim export FILE --out trace.npz|trace.csv``. The format is in recording.py and
docs/replay.md.
"""

from __future__ import annotations

import csv
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from beacon_sim.core.simulation import Simulation
from beacon_sim.core.types import Step
from beacon_sim.filters.loading import build_filter, filter_display_name, filter_names
from beacon_sim.filters.runner import FilterRunner
from beacon_sim.headless import RunResult
from beacon_sim.recording import Recording, RecordingError, load_recording
from beacon_sim.user_commands import apply_commands


class ReplayMismatch(RecordingError):
    """The replayed truth differs from the recorded one."""


def _is_safe_spec(spec: str) -> bool:
    """Built-in filters (and installed entry points) only: a recording never makes us
    import a module or a file it names."""
    return ":" not in spec


def replay_specs(recording: Recording, requested: list[str] | None) -> tuple[list[str], list[str]]:
    """(filters to run, recorded filters skipped): ``requested`` when given (even empty);
    otherwise the recorded built-in ones (named by module or file path: skipped)."""
    if requested is not None:
        return list(requested), []
    return ([s for s in recording.filters if _is_safe_spec(s)],
            [s for s in recording.filters if not _is_safe_spec(s)])


def replay_params(recording: Recording,
                  params: dict[str, dict[str, Any]] | None) -> dict[str, dict[str, Any]]:
    """The recorded filter parameters with ``params`` (from ``--set``) on top."""
    merged = recording.params
    for name, p in (params or {}).items():
        merged.setdefault(name, {}).update(p)
    return merged


def skipped_note(spec: str) -> str:
    """The line telling the user a recorded filter was not run, and how to run it."""
    return (f"note: recorded filter {spec} not run (a recording never makes beacon-sim import "
            f"code); pass --filter {spec} to run it")


def build_filters(specs: list[str], recording: Recording,
                  params: dict[str, dict[str, Any]] | None = None) -> dict[str, object]:
    """Construct the filters for a replay, named as a headless run names them."""
    built: dict[str, object] = {}
    for name, spec in zip(filter_names(specs), specs, strict=True):
        built[name] = build_filter(spec, recording.scenario, recording.seed, name=name,
                                   params=(params or {}).get(filter_display_name(spec)))
    return built


def replay_recording(recording: Recording, filters: list[str] | None = None,
                     params: dict[str, dict[str, Any]] | None = None,
                     verify: bool = True) -> RunResult:
    """Re-simulate a recording, feeding the filters; check the truth against the file.

    ``filters`` None runs the recorded built-in filters with the recorded parameters
    (filters named by module or file path are skipped: pass them explicitly). Raises
    :class:`ReplayMismatch` naming the first tick whose truth differs.
    """
    specs, skipped = replay_specs(recording, filters)
    built = build_filters(specs, recording, replay_params(recording, params))
    runner = FilterRunner(built)
    scenario = recording.scenario
    sim = Simulation(scenario, recording.seed)
    steps: list[Step] = []
    checked = 0
    t0 = time.perf_counter()
    sim_ns = 0
    for rec in recording.ticks:
        a = time.perf_counter_ns()
        if rec.commands:
            apply_commands(rec.commands, sim, built, scenario)
        step = sim.step(rec.control)
        sim_ns += time.perf_counter_ns() - a
        if verify:
            if rec.short_checksum is not None:
                if sim.truth_checksum[:8] != rec.short_checksum:
                    raise _mismatch(recording, rec.tick, rec.line, "its truth checksum")
                checked += 1
            cp = recording.checkpoints.get(rec.tick)
            if cp is not None and (cp["checksum"] != sim.truth_checksum
                                   or cp.get("pose") != [float(v) for v in sim.pose]):
                raise _mismatch(recording, _first_bad_tick(recording, rec.tick), rec.line,
                                "the checkpoint")
        steps.append(step)
        runner.feed(step)
    wall = time.perf_counter() - t0
    end = recording.end
    status = "no end line: checked tick by tick"
    if verify and end is not None:
        if end.get("ticks") != sim.tick or end["checksum"] != sim.truth_checksum:
            raise _mismatch(recording, sim.tick, len(recording.ticks), "the final checksum")
        status = "verified"
    elif verify and recording.ticks and checked == len(recording.ticks):
        status = "verified up to the last complete tick"
    result = RunResult(scenario, recording.seed, steps, runner, wall, sim_ns / 1e9, sim.truth_checksum)
    result.extra["replay"] = {
        "file": str(recording.path), "ticks": len(recording.ticks), "complete": recording.complete,
        "checksum_status": status if verify else "not checked",
        "recorded_checksum": end["checksum"] if end else None,
        "skipped_filters": skipped, "warnings": list(recording.warnings),
    }
    return result


def _first_bad_tick(recording: Recording, tick: int) -> int:
    prev = [k for k in recording.checkpoints if k < tick]
    return (max(prev) + 1) if prev else 1


def _mismatch(recording: Recording, tick: int, line: int, what: str) -> ReplayMismatch:
    return ReplayMismatch(
        f"{recording.path}:{line}: replay differs from the recording at tick {tick} "
        f"(t = {tick * recording.scenario.dt:g} s; checked against {what}): was it recorded by "
        f"another version of beacon-sim (recorded by {recording.header.get('program_version')})?")


def _as_usage_error(exc: Exception):
    from beacon_sim.cli import UsageError

    return UsageError(str(exc))


def _load(path: str) -> Recording:
    try:
        return load_recording(path)
    except RecordingError as exc:
        raise _as_usage_error(exc) from None


def replay_command(args) -> int:
    """``beacon-sim replay``: on screen when the window offers it, else headless."""
    from beacon_sim.cli import _filter_params, _print_run

    recording = _load(args.file)
    for note in recording.warnings:
        print(f"warning: {note}", file=sys.stderr)
    params = _filter_params(args)
    if not args.headless:
        show = _window_replay()
        if show is not None:
            return show(recording, args)
        print("note: the replay window is not available here; replaying headless", file=sys.stderr)
    try:
        result = replay_recording(recording, args.filters, params)
    except ReplayMismatch as exc:
        raise _as_usage_error(exc) from None
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
        _print_run(data)
    for track in result.runner.tracks.values():
        if track.failed:
            print(f"filter {track.name} failed: {track.failed}\n{track.traceback}", file=sys.stderr)
    return 0


def _window_replay():
    """The window's replay view (``beacon_sim.app.replay:show_replay(recording, args)``), if any."""
    try:
        import importlib

        module = importlib.import_module("beacon_sim.app.replay")
    except ImportError:
        return None
    return getattr(module, "show_replay", None)


# --------------------------------------------------------------------------------------------
# Export


def trace_arrays(recording: Recording) -> dict[str, np.ndarray]:
    """The recording re-simulated as flat arrays (no filter runs).

    Keys: ``truth_tick`` (T+1,), ``truth_time`` (T+1,) [s], ``truth`` (T+1, 3) [m, m, rad]
    (row 0 is the initial pose); ``control`` (T, 2) [m/s, rad/s] for ticks 1..T;
    ``meas_tick``, ``meas_time``, ``meas_sensor``, ``meas_kind``, ``meas_beacon_id`` (-1 for a
    fix), ``meas_z`` (M, 3) NaN-padded (bearing [rad]; range, bearing [m, rad]; pose x, y,
    theta; position x, y), ``meas_hdop``; ``event_tick``, ``event_time``, ``event_kind``,
    ``event_detail``, ``event_pose_before``, ``event_pose_after`` (E, 3; NaN when not a kidnap);
    ``command_tick``, ``command_json``; ``header_json`` (the recording's header).
    """
    result = replay_recording(recording, filters=[])
    steps = result.steps
    sc = recording.scenario
    truth = np.vstack([np.array(sc.initial_pose, dtype=float)] + [s.true_pose for s in steps])
    ticks = np.arange(len(steps) + 1)
    out: dict[str, np.ndarray] = {
        "truth_tick": ticks, "truth_time": ticks * sc.dt, "truth": truth,
        "control": np.array([[s.control.v, s.control.omega] for s in steps], dtype=float).reshape(-1, 2),
    }
    mt, msens, mkind, mid, mz, mh = [], [], [], [], [], []
    for s in steps:
        for m in s.measurements:
            fix = m.kind in ("pose", "position")
            for i in range(len(m)):
                mt.append(s.tick)
                msens.append(m.sensor)
                mkind.append(m.kind)
                mid.append(-1 if fix else int(m.beacon_ids[i]))
                row = np.full(3, np.nan)
                row[: m.z.shape[1]] = m.z[i]
                mz.append(row)
                mh.append(m.hdop)
    out["meas_tick"] = np.array(mt, dtype=int)
    out["meas_time"] = out["meas_tick"] * sc.dt
    out["meas_sensor"] = np.array(msens, dtype=str)
    out["meas_kind"] = np.array(mkind, dtype=str)
    out["meas_beacon_id"] = np.array(mid, dtype=int)
    out["meas_z"] = np.array(mz, dtype=float).reshape(-1, 3)
    out["meas_hdop"] = np.array(mh, dtype=float)
    ev = [e for s in steps for e in s.events]
    nan3 = np.full(3, np.nan)
    out["event_tick"] = np.array([e.tick for e in ev], dtype=int)
    out["event_time"] = np.array([e.time for e in ev], dtype=float)
    out["event_kind"] = np.array([e.kind for e in ev], dtype=str)
    out["event_detail"] = np.array([e.detail for e in ev], dtype=str)
    out["event_pose_before"] = np.array([nan3 if e.pose_before is None else e.pose_before
                                         for e in ev], dtype=float).reshape(-1, 3)
    out["event_pose_after"] = np.array([nan3 if e.pose_after is None else e.pose_after
                                        for e in ev], dtype=float).reshape(-1, 3)
    cmds = [(r.tick, json.dumps(c)) for r in recording.ticks for c in r.commands]
    out["command_tick"] = np.array([t for t, _ in cmds], dtype=int)
    out["command_json"] = np.array([c for _, c in cmds], dtype=str)
    out["header_json"] = np.array(json.dumps(recording.header))
    return out


def csv_paths(out: Path) -> dict[str, Path]:
    """The three files a ``.csv`` export writes: ``X.csv`` (one row per tick: truth and
    control), ``X.measurements.csv`` and ``X.events.csv``."""
    stem = out.with_suffix("")
    return {"ticks": out, "measurements": Path(f"{stem}.measurements.csv"),
            "events": Path(f"{stem}.events.csv")}


def write_csv(arrays: dict[str, np.ndarray], out: Path) -> list[Path]:
    paths = csv_paths(out)
    with paths["ticks"].open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["tick", "time_s", "x_m", "y_m", "theta_rad", "v_mps", "omega_radps"])
        ctrl = np.vstack([np.full((1, 2), np.nan), arrays["control"]])
        for i in range(len(arrays["truth_tick"])):
            w.writerow([int(arrays["truth_tick"][i]), repr(float(arrays["truth_time"][i])),
                        *(repr(float(v)) for v in arrays["truth"][i]),
                        *(repr(float(v)) for v in ctrl[i])])
    with paths["measurements"].open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["tick", "time_s", "sensor", "kind", "beacon_id", "z0", "z1", "z2", "hdop"])
        for i in range(len(arrays["meas_tick"])):
            w.writerow([int(arrays["meas_tick"][i]), repr(float(arrays["meas_time"][i])),
                        arrays["meas_sensor"][i], arrays["meas_kind"][i],
                        int(arrays["meas_beacon_id"][i]),
                        *(repr(float(v)) for v in arrays["meas_z"][i]),
                        repr(float(arrays["meas_hdop"][i]))])
    with paths["events"].open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["tick", "time_s", "kind", "detail", "x_before", "y_before", "theta_before",
                    "x_after", "y_after", "theta_after"])
        for i in range(len(arrays["event_tick"])):
            w.writerow([int(arrays["event_tick"][i]), repr(float(arrays["event_time"][i])),
                        arrays["event_kind"][i], arrays["event_detail"][i],
                        *(repr(float(v)) for v in arrays["event_pose_before"][i]),
                        *(repr(float(v)) for v in arrays["event_pose_after"][i])])
    return list(paths.values())


def export_command(args) -> int:
    """``beacon-sim export FILE --out trace.npz|trace.csv``."""
    from beacon_sim.cli import UsageError

    out = Path(args.out)
    if out.suffix not in (".npz", ".csv"):
        raise UsageError(f"--out {out}: expected a .npz or .csv file name")
    if not out.parent.is_dir():
        raise UsageError(f"--out {out}: no such folder {out.parent}")
    recording = _load(args.file)
    for note in recording.warnings:
        print(f"warning: {note}", file=sys.stderr)
    try:
        arrays = trace_arrays(recording)
    except ReplayMismatch as exc:
        raise _as_usage_error(exc) from None
    if out.suffix == ".npz":
        np.savez_compressed(out, **arrays)
        written = [out]
    else:
        written = write_csv(arrays, out)
    print(f"exported {len(arrays['control'])} ticks, {len(arrays['meas_tick'])} readings, "
          f"{len(arrays['event_tick'])} events to {', '.join(map(str, written))}")
    return 0


__all__ = ["ReplayMismatch", "export_command", "replay_command",
           "replay_recording", "trace_arrays"]
