"""A run as flat arrays for a notebook: ``.npz`` or ``.csv`` (``beacon-sim export``); the
same arrays feed the tidy tables (:mod:`beacon_sim.io.tables`) and the MCAP export
(:mod:`beacon_sim.io.mcap`).

Frames and units as everywhere: world frame, metres, radians, seconds.
"""

from __future__ import annotations

import io
import json
import re
import zipfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from beacon_sim.core.files import atomic_write, read_user_bytes
from beacon_sim.core.scenario import Scenario
from beacon_sim.core.sensor_kinds import table_rows
from beacon_sim.core.types import Step
from beacon_sim.hosting.runner import FilterTrack
from beacon_sim.io.recording import Recording
from beacon_sim.io.tables import (
    MAX_EXPORT_BYTES,
    POSE_AFTER,
    POSE_BEFORE,
    read_table_csv,
    reading_values,
    tables,
    write_table_csv,
    z_width,
)


def step_arrays(scenario: Scenario, steps: Sequence[Step]) -> dict[str, np.ndarray]:
    """Simulated ``steps`` (ticks 1..T of a run of ``scenario``) as flat arrays.

    Keys: ``truth_tick`` (T+1,), ``truth_time_s`` (T+1,) [s], ``truth`` (T+1, 3) [m, m, rad]
    (row 0 is the initial pose); ``control`` (T, 2) [m/s, rad/s] for ticks 1..T; the
    ``readings`` table as ``readings_<column>`` (M,) and the ``events`` table as
    ``events_<column>`` (E,), columns as in :mod:`beacon_sim.io.tables`. All in the world frame.
    """
    sc = scenario
    truth = np.vstack([np.array(sc.initial_pose, dtype=float)] + [s.true_pose for s in steps])
    ticks = np.arange(len(steps) + 1)
    out: dict[str, np.ndarray] = {
        "truth_tick": ticks, "truth_time_s": ticks * sc.dt, "truth": truth,
        "control": np.array([[s.control.v, s.control.omega] for s in steps], dtype=float).reshape(-1, 2),
    }
    mt, msens, mkind, mid, mz, mh = [], [], [], [], [], []
    width = z_width()
    for s in steps:
        for m in s.measurements:
            ids, zs = table_rows(m)   # a fix's or a scan's rows name no beacon (-1)
            for bid, zrow in zip(ids.tolist(), zs, strict=True):
                mt.append(s.tick)
                msens.append(m.sensor)
                mkind.append(m.kind)
                mid.append(int(bid))
                row = np.full(width, np.nan)
                row[: zs.shape[1]] = zrow
                mz.append(row)
                mh.append(m.hdop)
    kinds = np.array(mkind, dtype=str)
    out["readings_tick"] = np.array(mt, dtype=int)
    out["readings_time_s"] = out["readings_tick"] * sc.dt
    out["readings_sensor"] = np.array(msens, dtype=str)
    out["readings_kind"] = kinds
    out["readings_beacon_id"] = np.array(mid, dtype=int)
    for c, v in reading_values(kinds, np.array(mz, dtype=float).reshape(-1, width)).items():
        out[f"readings_{c}"] = v
    out["readings_hdop"] = np.array(mh, dtype=float)
    ev = [e for s in steps for e in s.events]
    nan3 = np.full(3, np.nan)
    out["events_tick"] = np.array([e.tick for e in ev], dtype=int)
    out["events_time_s"] = np.array([e.time for e in ev], dtype=float)
    out["events_kind"] = np.array([e.kind for e in ev], dtype=str)
    out["events_detail"] = np.array([e.detail for e in ev], dtype=str)
    before = np.array([nan3 if e.pose_before is None else e.pose_before for e in ev], dtype=float)
    after = np.array([nan3 if e.pose_after is None else e.pose_after for e in ev], dtype=float)
    for pose, cols in ((before.reshape(-1, 3), POSE_BEFORE), (after.reshape(-1, 3), POSE_AFTER)):
        for j, c in enumerate(cols):
            out[f"events_{c}"] = pose[:, j].copy()
    return out


def filter_arrays(tracks: Mapping[str, FilterTrack], n_ticks: int) -> dict[str, np.ndarray]:
    """Each filter's estimates over ticks 1..``n_ticks`` as arrays, one row per tick.

    Keys: ``filter_names`` (F,); ``est_mean`` (F, T, 3) [m, m, rad] and ``est_cov``
    (F, T, 3, 3) in the world frame, row ``k - 1`` for tick ``k``, NaN on ticks without an
    estimate (after the filter was switched off); ``filter_failed`` (F,) why it was switched
    off ("" when it ran to the end).
    """
    names = list(tracks)
    mean = np.full((len(names), n_ticks, 3), np.nan)
    cov = np.full((len(names), n_ticks, 3, 3), np.nan)
    for i, tr in enumerate(tracks.values()):
        if tr.ticks:
            rows = np.asarray(tr.ticks, dtype=int) - 1
            mean[i, rows] = np.asarray(tr.means, dtype=float)
            cov[i, rows] = np.asarray(tr.covs, dtype=float)
    return {"filter_names": np.array(names, dtype=str).reshape(len(names)),
            "est_mean": mean, "est_cov": cov,
            "filter_failed": np.array([tr.failed or "" for tr in tracks.values()],
                                      dtype=str).reshape(len(names))}


def trace_arrays(recording: Recording, steps: Sequence[Step],
                 tracks: Mapping[str, FilterTrack] | None = None) -> dict[str, np.ndarray]:
    """A recording, its re-simulated ``steps`` and the filters' ``tracks``
    (:func:`beacon_sim.runs.replay.replay_recording`) as flat arrays.

    Keys: those of :func:`step_arrays`, of :func:`filter_arrays` (when ``tracks`` is given),
    and ``command_tick``, ``command_json`` (the user's commands), ``header_json`` (the
    recording's header, files named without their folders: :func:`shareable_header`).
    """
    out = step_arrays(recording.scenario, steps)
    if tracks is not None:
        out.update(filter_arrays(tracks, len(steps)))
    cmds = [(r.tick, json.dumps(c)) for r in recording.ticks for c in r.commands]
    out["command_tick"] = np.array([t for t, _ in cmds], dtype=int)
    out["command_json"] = np.array([c for _, c in cmds], dtype=str)
    out["header_json"] = np.array(json.dumps(shareable_header(recording.header)))
    return out


#: The folders of a path in a filter spec or a file name (``C:``, ``dir/``, ``dir\``).
_FOLDERS = re.compile(r"(?:\b[A-Za-z]:)?[^\s=:]*[\\/]")


def without_folders(text: str) -> str:
    """``text`` with the folders of every path in it dropped: ``/a/b/f.py:Ekf`` ->
    ``f.py:Ekf``, ``alice=../s/alice.py:Ekf`` -> ``alice=alice.py:Ekf``; ``pkg.mod:Ekf``
    and built-in names unchanged."""
    return _FOLDERS.sub("", text)


def shareable_header(header: Mapping[str, Any]) -> dict[str, Any]:
    """A recording's header as an export carries it: the scenario's source and the filter
    specs name files by their file names, never by where they were on the machine that
    recorded (an export is shared; the scenario's text is in ``scenario_toml``)."""
    out = dict(header)
    if isinstance(out.get("scenario_source"), str):
        out["scenario_source"] = without_folders(out["scenario_source"])
    if isinstance(out.get("filters"), list):
        out["filters"] = [without_folders(f) if isinstance(f, str) else f for f in out["filters"]]
    return out


def csv_paths(out: Path) -> dict[str, Path]:
    """The files a ``.csv`` export writes, one per table of :mod:`beacon_sim.io.tables`:
    ``X.csv`` (truth: one row per tick, with the command), ``X.readings.csv``,
    ``X.events.csv`` and, when filters ran, ``X.estimates.csv`` (one row per filter and tick)."""
    stem = out.with_suffix("")
    return {"truth": out, "readings": Path(f"{stem}.readings.csv"),
            "events": Path(f"{stem}.events.csv"), "estimates": Path(f"{stem}.estimates.csv")}


#: Before 0.3.0 the readings file was ``X.measurements.csv``.
OLD_CSV_FILES = {"readings": "measurements"}


def write_csv(arrays: dict[str, np.ndarray], out: Path) -> list[Path]:
    paths = csv_paths(out)
    if "filter_names" not in arrays:
        del paths["estimates"]
    tabs = tables(arrays)
    return [write_table_csv(tabs[name], path) for name, path in paths.items()]


def write_export(arrays: dict[str, np.ndarray], out: Path) -> list[Path]:
    """Write ``arrays`` to ``out`` (``.npz``: one compressed file; ``.csv``: one file per
    table, see :func:`csv_paths`); returns the files written. ``.mcap`` is
    :func:`beacon_sim.io.mcap.write_mcap`."""
    if out.suffix == ".npz":
        with atomic_write(out, "wb", what="export") as fh:  # the old file stays until this one is whole
            np.savez_compressed(fh, allow_pickle=False, **arrays)
        return [out]
    if out.suffix == ".csv":
        return write_csv(arrays, out)
    raise ValueError(f"{out}: expected a .npz, .csv or .mcap file name")


def check_unpacked_size(path: Path, data: bytes, cap: int) -> None:
    """Refuse a ``.npz`` whose members would unpack to more than ``cap`` bytes in all (a
    decompression bomb: a small file that inflates to gigabytes), read from the archive's
    directory before anything is decompressed; ``ValueError`` naming the file."""
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as z:
            total = sum(info.file_size for info in z.infolist())
    except (zipfile.BadZipFile, OSError, ValueError) as exc:
        raise ValueError(f"{path}: not a .npz export (not a zip archive: {str(exc)[:60]})") from None
    if total > cap:
        raise ValueError(f"{path}: unpacks to {total:,} bytes: an export holds at most {cap:,}")


def load_export(path: str | Path) -> dict[str, dict[str, np.ndarray]]:
    """The tables (:func:`beacon_sim.io.tables.tables`) of an export: a ``.npz`` file or the
    ``.csv`` files of :func:`csv_paths` (give ``X.csv``), written now or before 0.3.0 (old
    names are renamed). A table the export does not have (estimates without filters) is
    absent. Raises ``ValueError`` naming the file for anything else."""
    path = Path(path)
    if path.suffix == ".npz":
        data = read_user_bytes(path, what="export", cap=MAX_EXPORT_BYTES)
        check_unpacked_size(path, data, MAX_EXPORT_BYTES)
        try:
            with np.load(io.BytesIO(data), allow_pickle=False) as z:
                arrays = {k: z[k] for k in z.files}
        except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
            raise ValueError(f"{path}: not a readable .npz export ({str(exc)[:80]})") from None
        if "truth" not in arrays:
            raise ValueError(f"{path}: not a beacon-sim export (no 'truth' array)")
        out = tables(arrays)
        if "filter_names" not in arrays:
            del out["estimates"]
        return out
    if path.suffix != ".csv":
        raise ValueError(f"{path}: expected a .npz or .csv export")
    out = {}
    for name, p in csv_paths(path).items():
        if not p.is_file() and name in OLD_CSV_FILES:
            p = Path(f"{path.with_suffix('')}.{OLD_CSV_FILES[name]}.csv")
        if p.is_file():
            out[name] = read_table_csv(p, name)
        elif name != "estimates":
            raise ValueError(f"{p}: missing (a .csv export has {', '.join(csv_paths(path))} files)")
    return out
