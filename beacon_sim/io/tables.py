"""A run as tidy tables: one name per field in the Python API, the DataFrames, ``.npz`` and ``.csv``.

A table is a dict ``column name -> 1-D array`` (all the same length), so ``pd.DataFrame(t)``
takes it as it is and ``df.plot`` / seaborn take the frame directly. The tables of a run:

``truth``      one row per tick (tick 0 is the start): the true pose and the command
``estimates``  long form: one row per filter and tick with an estimate: the mean, the upper
               triangle of the covariance, the error against the truth and the NEES
``readings``   one row per reading: sensor, kind, beacon, and the reading in named columns
               with units (NaN where the kind has no such number)
``events``     one row per event (kidnap, blackout, ...), with the kidnap's poses

Column names carry their unit: ``_m`` metres, ``_rad`` radians, ``_s`` seconds, ``_mps`` m/s,
``_radps`` rad/s; covariances are in the products of those units, NEES has none. Frames as
everywhere: world frame, theta counter-clockwise from +x. ``.npz`` keys are
``<table>_<column>`` for the readings and events (``readings_range_m``), so a field has the
same name everywhere; files written with the names before 0.3.0 (``meas_z``,
``event_pose_before``, ``time_s`` / ``z0..z2`` CSV columns, ...) load through
:func:`upgrade_arrays` and :func:`read_csv_tables`.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from beacon_sim.core import sensor_kinds
from beacon_sim.core.csv_cells import csv_writer, unguard_cell
from beacon_sim.core.files import atomic_write, read_user_text
from beacon_sim.core.metrics import pose_errors

TRUTH_COLUMNS = ("tick", "time_s", "x_m", "y_m", "theta_rad", "v_mps", "omega_radps")
#: The covariance columns: the upper triangle of the 3 x 3 matrix over x [m], y [m], theta [rad].
COV_COLUMNS = ("cov_xx", "cov_xy", "cov_xt", "cov_yy", "cov_yt", "cov_tt")
UPPER = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))
ESTIMATE_COLUMNS = ("tick", "time_s", "filter", "x_m", "y_m", "theta_rad", *COV_COLUMNS,
                    "err_x_m", "err_y_m", "err_theta_rad", "err_pos_m", "nees")
#: The built-in kinds' reading columns, in the tables' order; a registered kind's own
#: columns follow them (:func:`value_columns`). Each kind's row order is its record's
#: ``columns`` (core/sensor_kinds.py; a range finder's row is one beam: its range and its
#: angle from the heading).
VALUE_COLUMNS = ("range_m", "bearing_rad", "x_m", "y_m", "theta_rad")
READING_COLUMNS = ("tick", "time_s", "sensor", "kind", "beacon_id", *VALUE_COLUMNS, "hdop")


def value_columns() -> tuple[str, ...]:
    """:data:`VALUE_COLUMNS` and then the columns of registered kinds that it lacks."""
    extra = [c for c in sensor_kinds.value_columns() if c not in VALUE_COLUMNS]
    return (*VALUE_COLUMNS, *extra)


def reading_columns() -> tuple[str, ...]:
    """The readings table's columns (:data:`READING_COLUMNS` with every registered kind's)."""
    return ("tick", "time_s", "sensor", "kind", "beacon_id", *value_columns(), "hdop")


def z_width() -> int:
    """Width of the NaN-padded reading rows: the widest kind's row, at least 3."""
    return max(3, *(k.dims for k in sensor_kinds.KINDS.values()))


POSE_BEFORE = ("x_before_m", "y_before_m", "theta_before_rad")
POSE_AFTER = ("x_after_m", "y_after_m", "theta_after_rad")
EVENT_COLUMNS = ("tick", "time_s", "kind", "detail", *POSE_BEFORE, *POSE_AFTER)
TABLES = ("truth", "estimates", "readings", "events")

#: ``.npz`` keys renamed in 0.3.0 (old -> new); ``meas_z`` and the event poses are split.
OLD_NPZ_KEYS = {"truth_time": "truth_time_s", "meas_tick": "readings_tick",
                "meas_time": "readings_time_s", "meas_sensor": "readings_sensor",
                "meas_kind": "readings_kind", "meas_beacon_id": "readings_beacon_id",
                "meas_hdop": "readings_hdop", "event_tick": "events_tick",
                "event_time": "events_time_s", "event_kind": "events_kind",
                "event_detail": "events_detail"}
#: CSV columns renamed in 0.3.0, per file (``z0..z2`` are split by kind).
OLD_CSV_COLUMNS = {"events": {"x_before": "x_before_m", "y_before": "y_before_m",
                              "theta_before": "theta_before_rad", "x_after": "x_after_m",
                              "y_after": "y_after_m", "theta_after": "theta_after_rad"}}
_INT = {"tick", "beacon_id"}
_STR = {"filter", "sensor", "kind", "detail"}


def reading_values(kinds: np.ndarray, z: np.ndarray) -> dict[str, np.ndarray]:
    """The (M, w) NaN-padded readings ``z`` of kinds ``kinds`` (M,) as the named columns of
    :func:`value_columns` (each kind's columns from its record)."""
    kinds = np.asarray(kinds)
    z = np.asarray(z, dtype=float).reshape(len(kinds), -1)
    out = {c: np.full(len(z), np.nan) for c in value_columns()}
    for kind in sensor_kinds.KINDS.values():
        rows = kinds == kind.name
        for j, c in enumerate(kind.columns):
            out[c][rows] = z[rows, j]
    return out


def reading_matrix(readings: Mapping[str, np.ndarray]) -> np.ndarray:
    """The inverse of :func:`reading_values`: each reading's numbers in the sensor's ``z``
    order, (M, 3) NaN-padded."""
    kinds = np.asarray(readings["kind"])
    z = np.full((len(kinds), z_width()), np.nan)
    for kind in sensor_kinds.KINDS.values():
        rows = kinds == kind.name
        for j, c in enumerate(kind.columns):
            if c in readings:
                z[rows, j] = np.asarray(readings[c], dtype=float)[rows]
    return z


def prefixed(arrays: Mapping[str, np.ndarray], table: str) -> dict[str, np.ndarray]:
    """The columns of ``table`` (``readings`` or ``events``) held in flat arrays as
    ``<table>_<column>``."""
    cut = len(table) + 1
    return {k[cut:]: v for k, v in arrays.items() if k.startswith(f"{table}_")}


def upgrade_arrays(arrays: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Flat export arrays with the names of today, from a file written before 0.3.0 or now."""
    out = {OLD_NPZ_KEYS.get(k, k): v for k, v in arrays.items()
           if k not in ("meas_z", "event_pose_before", "event_pose_after")}
    if "meas_z" in arrays:
        for c, v in reading_values(arrays["meas_kind"], arrays["meas_z"]).items():
            out[f"readings_{c}"] = v
    for old, cols in (("event_pose_before", POSE_BEFORE), ("event_pose_after", POSE_AFTER)):
        if old in arrays:
            pose = np.asarray(arrays[old], dtype=float).reshape(-1, 3)
            out.update({f"events_{c}": pose[:, j].copy() for j, c in enumerate(cols)})
    return out


def truth_table(arrays: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    truth = np.asarray(arrays["truth"], dtype=float).reshape(-1, 3)
    ctrl = np.vstack([np.full((1, 2), np.nan), np.asarray(arrays["control"], dtype=float).reshape(-1, 2)])
    return {"tick": np.asarray(arrays["truth_tick"], dtype=int), "time_s": np.asarray(arrays["truth_time_s"]),
            "x_m": truth[:, 0], "y_m": truth[:, 1], "theta_rad": truth[:, 2],
            "v_mps": ctrl[:, 0], "omega_radps": ctrl[:, 1]}


def estimate_table(arrays: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Long form: one row per filter and tick with an estimate (filters in order, then ticks)."""
    names = [str(n) for n in arrays.get("filter_names", [])]
    cols: dict[str, list] = {c: [] for c in ESTIMATE_COLUMNS}
    truth = np.asarray(arrays["truth"], dtype=float)[1:]
    time = np.asarray(arrays["truth_time_s"], dtype=float)[1:]
    for i, name in enumerate(names):
        mean, cov = np.asarray(arrays["est_mean"][i]), np.asarray(arrays["est_cov"][i])
        rows = np.flatnonzero(~np.isnan(mean).all(axis=1))
        err = pose_errors(mean[rows], truth[rows])
        nees = np.full(len(rows), np.nan)
        with np.errstate(all="ignore"):
            for j, r in enumerate(rows):  # a singular or NaN covariance has no NEES
                try:
                    nees[j] = float(err[j] @ np.linalg.solve(cov[r], err[j]))
                except np.linalg.LinAlgError:
                    pass
        cols["tick"].append(rows + 1)
        cols["time_s"].append(time[rows])
        cols["filter"].append(np.full(len(rows), name))
        for j, c in enumerate(("x_m", "y_m", "theta_rad")):
            cols[c].append(mean[rows, j])
        for c, (a, b) in zip(COV_COLUMNS, UPPER, strict=True):
            cols[c].append(cov[rows, a, b])
        for j, c in enumerate(("err_x_m", "err_y_m", "err_theta_rad")):
            cols[c].append(err[:, j])
        cols["err_pos_m"].append(np.hypot(err[:, 0], err[:, 1]))
        cols["nees"].append(nees)
    return {c: _concat(v, c) for c, v in cols.items()}


def _concat(parts: list, column: str) -> np.ndarray:
    if parts:
        return np.concatenate(parts)
    return np.array([], dtype=int if column in _INT else str if column in _STR else float)


def tables(arrays: Mapping[str, np.ndarray]) -> dict[str, dict[str, np.ndarray]]:
    """The tables of :data:`TABLES` from a run's flat export arrays (old names upgraded)."""
    a = upgrade_arrays(arrays)
    readings, events = prefixed(a, "readings"), prefixed(a, "events")
    return {"truth": truth_table(a), "estimates": estimate_table(a),
            "readings": {c: readings[c] for c in reading_columns() if c in READING_COLUMNS or c in readings},
            "events": {c: events[c] for c in EVENT_COLUMNS}}


def metrics_table(metrics: Mapping) -> dict[str, np.ndarray]:
    """``run --json``'s per-filter figures, one row per filter: ``filter``, then every
    number any filter has (``pos_rmse_m``, ``anees``, ...; NaN where a filter has none) and
    ``failed`` (why it was switched off, "" when it ran to the end)."""
    filters = dict(metrics.get("filters", {}))
    keys: list[str] = []
    for fig in filters.values():
        keys += [k for k, v in fig.items() if k != "failed" and isinstance(v, int | float)
                 and not isinstance(v, bool) and k not in keys]
    out = {"filter": np.array(list(filters), dtype=str)}
    for k in keys:
        out[k] = np.array([float(fig.get(k, np.nan)) for fig in filters.values()], dtype=float)
    out["failed"] = np.array([str(fig.get("failed") or "") for fig in filters.values()], dtype=str)
    return out


#: The largest export file read back [bytes].
MAX_EXPORT_BYTES = 2**30


# -- CSV --------------------------------------------------------------------------------------

def write_table_csv(table: Mapping[str, np.ndarray], path: Path) -> Path:
    """One table as a CSV file, a header of its column names; floats as ``repr`` (exact)."""
    cols = list(table)
    n = len(next(iter(table.values()))) if table else 0
    with atomic_write(path, "w", newline="", what="export") as f:  # whole, or the old file stays
        w = csv_writer(f)
        w.writerow(cols)
        data = [table[c] for c in cols]
        for i in range(n):
            w.writerow([_cell(col[i]) for col in data])
    return path


def _cell(v) -> str:
    if isinstance(v, np.floating | float):
        return repr(float(v))
    if isinstance(v, np.integer | int):
        return str(int(v))
    return str(v)


def read_table_csv(path: Path, name: str) -> dict[str, np.ndarray]:
    """A table written by :func:`write_table_csv` (or before 0.3.0) back as columns."""
    text = read_user_text(path, what="export", cap=MAX_EXPORT_BYTES)
    rows = list(csv.reader(io.StringIO(text, newline="")))
    if not rows:
        raise ValueError(f"{path}: empty file, expected a header line")
    header = [OLD_CSV_COLUMNS.get(name, {}).get(c, c) for c in rows[0]]
    body = rows[1:]
    out: dict[str, np.ndarray] = {}
    for j, c in enumerate(header):
        vals = [unguard_cell(r[j]) for r in body]
        if c in _STR:
            out[c] = np.array(vals, dtype=str)
        elif c in _INT:
            out[c] = np.array([int(v) for v in vals], dtype=int)
        else:
            try:
                out[c] = np.array([float(v) for v in vals], dtype=float)
            except ValueError:
                out[c] = np.array(vals, dtype=str)
    if name == "readings" and "z0" in out:  # before 0.3.0: z0..z2 in the sensor's order
        z = np.column_stack([out.pop(f"z{j}") for j in range(3)])
        values = reading_values(out["kind"], z)
        hdop = out.pop("hdop")
        out.update(values)
        out["hdop"] = hdop
    return out
