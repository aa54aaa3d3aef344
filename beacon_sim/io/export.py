"""A run as flat arrays for a notebook: ``.npz`` or ``.csv`` (``beacon-sim export``); the
same arrays feed the MCAP export (:mod:`beacon_sim.io.mcap`).

Frames and units as everywhere: world frame, metres, radians, seconds.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from beacon_sim.core.scenario import Scenario
from beacon_sim.core.types import Step
from beacon_sim.filters.runner import FilterTrack
from beacon_sim.io.recording import Recording


def step_arrays(scenario: Scenario, steps: Sequence[Step]) -> dict[str, np.ndarray]:
    """Simulated ``steps`` (ticks 1..T of a run of ``scenario``) as flat arrays.

    Keys: ``truth_tick`` (T+1,), ``truth_time`` (T+1,) [s], ``truth`` (T+1, 3) [m, m, rad]
    (row 0 is the initial pose); ``control`` (T, 2) [m/s, rad/s] for ticks 1..T;
    ``meas_tick``, ``meas_time``, ``meas_sensor``, ``meas_kind``, ``meas_beacon_id`` (-1 for a
    fix), ``meas_z`` (M, 3) NaN-padded (bearing [rad]; range, bearing [m, rad]; pose x, y,
    theta; position x, y), ``meas_hdop``; ``event_tick``, ``event_time``, ``event_kind``,
    ``event_detail``, ``event_pose_before``, ``event_pose_after`` (E, 3; NaN when not a kidnap).
    All in the world frame.
    """
    sc = scenario
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
    recording's header).
    """
    out = step_arrays(recording.scenario, steps)
    if tracks is not None:
        out.update(filter_arrays(tracks, len(steps)))
    cmds = [(r.tick, json.dumps(c)) for r in recording.ticks for c in r.commands]
    out["command_tick"] = np.array([t for t, _ in cmds], dtype=int)
    out["command_json"] = np.array([c for _, c in cmds], dtype=str)
    out["header_json"] = np.array(json.dumps(recording.header))
    return out


def csv_paths(out: Path) -> dict[str, Path]:
    """The files a ``.csv`` export writes: ``X.csv`` (one row per tick: truth and control),
    ``X.measurements.csv``, ``X.events.csv`` and, when filters ran, ``X.estimates.csv`` (one
    row per filter and tick)."""
    stem = out.with_suffix("")
    return {"ticks": out, "measurements": Path(f"{stem}.measurements.csv"),
            "events": Path(f"{stem}.events.csv"), "estimates": Path(f"{stem}.estimates.csv")}


#: The covariance columns of ``X.estimates.csv``: the upper triangle of the 3 x 3 matrix.
COV_COLUMNS = ("cov_xx", "cov_xy", "cov_xt", "cov_yy", "cov_yt", "cov_tt")
_UPPER = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


def write_csv(arrays: dict[str, np.ndarray], out: Path) -> list[Path]:
    paths = csv_paths(out)
    if "filter_names" not in arrays:
        del paths["estimates"]
    else:
        with paths["estimates"].open("w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["tick", "time_s", "filter", "x_m", "y_m", "theta_rad", *COV_COLUMNS])
            for i, name in enumerate(arrays["filter_names"]):
                for k in range(arrays["est_mean"].shape[1]):
                    m, c = arrays["est_mean"][i, k], arrays["est_cov"][i, k]
                    if np.isnan(m).all():
                        continue  # no estimate on this tick (the filter was switched off)
                    w.writerow([k + 1, repr(float(arrays["truth_time"][k + 1])), str(name),
                                *(repr(float(v)) for v in m),
                                *(repr(float(c[a, b])) for a, b in _UPPER)])
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


def write_export(arrays: dict[str, np.ndarray], out: Path) -> list[Path]:
    """Write ``arrays`` to ``out`` (``.npz``: one compressed file; ``.csv``: three files, see
    :func:`csv_paths`); returns the files written."""
    if out.suffix == ".npz":
        np.savez_compressed(out, allow_pickle=False, **arrays)
        return [out]
    if out.suffix == ".csv":
        return write_csv(arrays, out)
    raise ValueError(f"{out}: expected a .npz or .csv file name")
