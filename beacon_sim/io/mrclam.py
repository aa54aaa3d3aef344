"""Reading the UTIAS MRCLAM data sets (Leung et al., IJRR 2011; docs/references.md).

- Reads ``RobotN_Odometry.dat`` (t, v, omega), ``RobotN_Measurement.dat`` (t, barcode, range,
  bearing), ``RobotN_Groundtruth.dat`` (t, x, y, theta), ``Landmark_Groundtruth.dat`` and
  ``Barcodes.dat`` of one folder (4 comment lines, CRLF, tabs or spaces). A malformed or
  missing file is an error naming the file and line.
- Barcodes are mapped to subjects through that folder's ``Barcodes.dat``; sightings of robots
  (subjects 1-5) and unknown barcodes are dropped (robot sightings are kept apart on request,
  for the team run: ``load_mrclam(..., robot_sightings=True)``); readings sharing a time stamp form one
  update.
- Ground truth is interpolated to any times; only times inside ground truth count.
- Where the data set is: :func:`find_dataset` (a folder given, else the environment variable
  ``BEACON_SIM_MRCLAM``; docs/mrclam.md says where MRCLAM comes from).

Frames and units: metres, radians, world frame of the data set (Vicon), bearings relative to
the heading and wrapped to [-pi, pi). Running filters on the data: beacon_sim/runs/mrclam/.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.core.files import read_user_bytes
from beacon_sim.errors import BeaconSimError

#: Subjects 1-5 are the robots in every MRCLAM data set; landmarks are 6 and up.
ROBOT_SUBJECTS = range(1, 6)
#: Ground-truth samples further apart than this [s] are a gap: no evaluation inside it.
MAX_TRUTH_GAP_S = 0.5
#: Longest span of one robot's time stamps [s] (the data sets' runs last under an hour).
MAX_SPAN_S = 86_400
#: Largest MRCLAM ``.dat`` file read [bytes] (the data sets' largest is about 3 MB).
MAX_TABLE_BYTES = 256 * 2**20


class MrclamError(BeaconSimError):
    """A missing or malformed MRCLAM file; the message names the file and line."""


#: The environment variable that says where MRCLAM is: one data set's folder, or a folder
#: holding data set folders (``Dataset6``, ``MRCLAM_Dataset6``, ...).
MRCLAM_VARIABLE = "BEACON_SIM_MRCLAM"
#: The data set taken from a folder of data sets: the one this project's MRCLAM settings,
#: tests and figures were measured on.
DEFAULT_DATASET = 6
#: Where a user reads how to get MRCLAM and point the program at it.
MRCLAM_DOC = "docs/mrclam.md"


def find_dataset(where: str | Path | None = None, number: int = DEFAULT_DATASET) -> Path:
    """The folder of an MRCLAM data set (the one place that decides where MRCLAM is).

    ``where``: a data set's folder (it holds ``Barcodes.dat``), or a folder holding data set
    folders, of which ``Dataset<number>`` or ``MRCLAM_Dataset<number>`` is taken; None or
    empty: the environment variable :data:`MRCLAM_VARIABLE`. Raises :class:`MrclamError`
    naming the variable and the command-line argument when no data set is there.
    """
    origin = ""
    if where is None or str(where) == "":
        where = os.environ.get(MRCLAM_VARIABLE, "")
        origin = f" (from {MRCLAM_VARIABLE})"
    how = (f"give a data set's folder (beacon-sim mrclam DIR), or set {MRCLAM_VARIABLE} to it "
           f"or to the folder holding Dataset{number}; {MRCLAM_DOC} says where MRCLAM comes from")
    if not str(where):
        raise MrclamError(f"no MRCLAM data set given: {how}")
    folder = Path(where).expanduser()
    if not folder.is_dir():
        raise MrclamError(f"{folder}{origin}: no such folder (expected an MRCLAM data set "
                          f"folder): {how}")
    if (folder / "Barcodes.dat").is_file():
        return folder
    for name in (f"Dataset{number}", f"MRCLAM_Dataset{number}"):
        if (folder / name).is_dir():
            return folder / name
    raise MrclamError(f"{folder}{origin}: neither an MRCLAM data set (no Barcodes.dat) nor a "
                      f"folder holding Dataset{number} or MRCLAM_Dataset{number}: {how}")


#: Bad data (refused, naming the file, line and column): a coordinate or range beyond this
#: [m] (the data sets' room is about 6 m by 8 m), an angle beyond this [rad] (headings and
#: bearings are wrapped, so a few turns at most), a speed beyond this [m/s] or turn rate
#: [rad/s], a subject or barcode beyond this number.
MAX_COORD_M = 1e6
MAX_ANGLE_RAD = 1e3
MAX_SPEED = 100.0
MAX_TURN = 100.0
MAX_ID = 1e9
#: (column name, lowest, highest) of each file's columns, for :func:`read_table`.
_T = (-math.inf, math.inf)  # time stamps: any finite number (their order is checked later)
COLUMNS: dict[str, list[tuple[str, float, float]]] = {
    "Barcodes.dat": [("subject", 0, MAX_ID), ("barcode", 0, MAX_ID)],
    "Landmark_Groundtruth.dat": [("subject", 0, MAX_ID), ("x", -MAX_COORD_M, MAX_COORD_M),
                                 ("y", -MAX_COORD_M, MAX_COORD_M), ("sigma_x", 0, MAX_COORD_M),
                                 ("sigma_y", 0, MAX_COORD_M)],
    "Odometry": [("time", *_T), ("v", -MAX_SPEED, MAX_SPEED), ("omega", -MAX_TURN, MAX_TURN)],
    "Measurement": [("time", *_T), ("barcode", 0, MAX_ID), ("range", 0, MAX_COORD_M),
                    ("bearing", -MAX_ANGLE_RAD, MAX_ANGLE_RAD)],
    "Groundtruth": [("time", *_T), ("x", -MAX_COORD_M, MAX_COORD_M), ("y", -MAX_COORD_M, MAX_COORD_M),
                    ("theta", -MAX_ANGLE_RAD, MAX_ANGLE_RAD)],
}


def _check_ranges(path: Path, table: np.ndarray, lines: list[int],
                  ranges: list[tuple[str, float, float]]) -> None:
    """Refuse the first value outside its column's range as bad data (file, line, column)."""
    for j, (name, lo, hi) in enumerate(ranges):
        bad = np.flatnonzero((table[:, j] < lo) | (table[:, j] > hi))
        if bad.size:
            i = int(bad[0])
            raise MrclamError(f"{path}:{lines[i]}: bad data: {name} = {table[i, j]:g} (expected "
                              f"{lo:g} to {hi:g})")


def read_table(path: Path, ncols: int, columns: str,
               ranges: list[tuple[str, float, float]] | None = None) -> np.ndarray:
    """Rows of ``ncols`` numbers from an MRCLAM ``.dat`` file, shape (n, ncols).

    Lines starting with ``#`` and blank lines are skipped; CRLF and tabs/spaces are fine.
    ``ranges``: (name, lowest, highest) per column; a value outside is refused as bad data.
    """
    if not path.exists():
        raise MrclamError(f"{path}: missing (an MRCLAM folder holds {path.name} with columns "
                          f"{columns})")
    data = read_user_bytes(path, what="MRCLAM data file", cap=MAX_TABLE_BYTES, error=MrclamError)
    try:
        raw = data.decode("ascii")
    except UnicodeDecodeError as exc:
        bad_line = data[: exc.start].count(b"\n") + 1
        raise MrclamError(f"{path}:{bad_line}: not a text line (byte {exc.start})") from None
    rows: list[list[float]] = []
    numbers: list[int] = []
    for n, line in enumerate(raw.splitlines(), start=1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        parts = s.split()
        if len(parts) != ncols:
            raise MrclamError(f"{path}:{n}: expected {ncols} columns ({columns}), "
                              f"found {len(parts)}: {s[:60]!r}")
        try:
            row = [float(p) for p in parts]
        except ValueError:
            raise MrclamError(f"{path}:{n}: not a number in {s[:60]!r}") from None
        if not all(math.isfinite(v) for v in row):
            raise MrclamError(f"{path}:{n}: not a finite number in {s[:60]!r}")
        rows.append(row)
        numbers.append(n)
    if not rows:
        raise MrclamError(f"{path}: no data rows (columns {columns})")
    table = np.array(rows, dtype=float)
    if ranges is not None:
        _check_ranges(path, table, numbers, ranges)
    return table


@dataclass
class MrclamData:
    """One robot of one MRCLAM folder, cleaned.

    Attributes
    ----------
    odometry : ndarray (n, 3)
        ``t [s], v [m/s], omega [rad/s]``, sorted by time (stable: repeated stamps kept in
        file order; the last of them governs).
    measurements : ndarray (m, 4)
        ``t [s], subject, range [m], bearing [rad]``, landmarks only, sorted by time.
    groundtruth : ndarray (g, 4)
        ``t [s], x [m], y [m], theta [rad]``, strictly increasing times.
    landmarks : dict subject -> (x, y) [m]
    dropped : dict
        Counts of rows dropped: ``robot_sightings``, ``unknown_barcodes``, ``unknown_landmarks``
        (barcode of a subject with no landmark position), ``duplicates``.
    sightings : ndarray (k, 4)
        ``t [s], subject, range [m], bearing [rad]``: the sightings of the other robots
        (subjects 1-5 other than this one), sorted by time, one per robot and time stamp;
        filled only when loaded with ``robot_sightings=True``, else empty.
    """

    folder: Path
    robot: int
    odometry: np.ndarray
    measurements: np.ndarray
    groundtruth: np.ndarray
    landmarks: dict[int, tuple[float, float]]
    barcodes: dict[int, int]
    dropped: dict[str, int] = field(default_factory=dict)
    sightings: np.ndarray = field(default_factory=lambda: np.empty((0, 4)))

    @property
    def t0(self) -> float:
        """Time of the first odometry row [s] (Unix epoch): the run starts there."""
        return float(self.odometry[0, 0])

    def truth_at(self, times) -> tuple[np.ndarray, np.ndarray]:
        """Ground truth interpolated to ``times``: poses (k, 3) and a mask (k,) of the times
        that lie inside the ground truth (no gap longer than ``MAX_TRUTH_GAP_S``)."""
        return interpolate_truth(self.groundtruth, np.asarray(times, dtype=float))


def interpolate_truth(gt: np.ndarray, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Linear interpolation of x, y and the unwrapped heading; heading wrapped after."""
    t = gt[:, 0]
    poses = np.empty((times.shape[0], 3))
    poses[:, 0] = np.interp(times, t, gt[:, 1])
    poses[:, 1] = np.interp(times, t, gt[:, 2])
    poses[:, 2] = wrap(np.interp(times, t, np.unwrap(gt[:, 3])))
    j = np.clip(np.searchsorted(t, times), 1, len(t) - 1)
    ok = (times >= t[0]) & (times <= t[-1]) & ((t[j] - t[j - 1]) <= MAX_TRUTH_GAP_S)
    return poses, ok


def _check_time_span(folder: Path, robot: int, tables: dict[str, np.ndarray]) -> None:
    """Refuse time stamps spread over more than :data:`MAX_SPAN_S` (a row at t = 1e12 among
    rows of 2009 would have a run step through millennia), naming the file and the row's
    time farthest from the odometry's median."""
    t_all = np.concatenate([t[:, 0] for t in tables.values()])
    span = float(t_all.max() - t_all.min())
    if span <= MAX_SPAN_S:
        return
    centre = float(np.median(tables["Odometry"][:, 0]))
    name, worst = max(((n, float(t[np.argmax(np.abs(t[:, 0] - centre)), 0])) for n, t in tables.items()),
                      key=lambda item: abs(item[1] - centre))
    raise MrclamError(f"{folder / f'Robot{robot}_{name}.dat'}: a time stamp of {worst:.6g} s lies "
                      f"{abs(worst - centre):.4g} s from the odometry's median ({centre:.6g} s): a data "
                      f"set's time stamps span at most {MAX_SPAN_S:,} s (one day)")


def load_mrclam(folder: str | Path | None, robot: int, robot_sightings: bool = False) -> MrclamData:
    """Load and clean one robot of an MRCLAM data set. ``folder``: as :func:`find_dataset`
    takes it (None: ``$BEACON_SIM_MRCLAM``). ``robot_sightings`` also keeps the sightings of
    the other robots in ``sightings`` (the landmark readings, ``dropped`` and everything
    else are the same either way)."""
    if robot not in ROBOT_SUBJECTS:
        raise MrclamError(f"--robot {robot}: expected 1 to 5")
    folder = find_dataset(folder)
    bc = read_table(folder / "Barcodes.dat", 2, "subject, barcode", COLUMNS["Barcodes.dat"])
    lm = read_table(folder / "Landmark_Groundtruth.dat", 5, "subject, x, y, sigma_x, sigma_y",
                    COLUMNS["Landmark_Groundtruth.dat"])
    od = read_table(folder / f"Robot{robot}_Odometry.dat", 3, "time, v, omega", COLUMNS["Odometry"])
    ms = read_table(folder / f"Robot{robot}_Measurement.dat", 4, "time, barcode, range, bearing",
                    COLUMNS["Measurement"])
    gt = read_table(folder / f"Robot{robot}_Groundtruth.dat", 4, "time, x, y, theta",
                    COLUMNS["Groundtruth"])

    _check_time_span(folder, robot, {"Odometry": od, "Measurement": ms, "Groundtruth": gt})
    barcodes = {int(b): int(s) for s, b in bc}
    landmarks = {int(r[0]): (float(r[1]), float(r[2])) for r in lm}
    od = od[np.argsort(od[:, 0], kind="stable")]
    gt = gt[np.argsort(gt[:, 0], kind="stable")]
    _, first = np.unique(gt[:, 0], return_index=True)
    gt = gt[first]
    ms = ms[np.argsort(ms[:, 0], kind="stable")]

    subjects = np.array([barcodes.get(int(b), -1) for b in ms[:, 1]], dtype=int)
    robot_rows = np.isin(subjects, list(ROBOT_SUBJECTS))
    unknown = subjects < 0
    no_position = ~robot_rows & ~unknown & ~np.isin(subjects, list(landmarks))
    keep = ~(robot_rows | unknown | no_position)
    all_rows = np.column_stack([ms[:, 0], subjects, ms[:, 2], ms[:, 3]])
    ms = all_rows[keep]
    # The same landmark twice at one time stamp: keep the first reading.
    seen: set[tuple[float, int]] = set()
    dup = np.zeros(len(ms), dtype=bool)
    for i, (t, s) in enumerate(zip(ms[:, 0].tolist(), ms[:, 1].astype(int).tolist(), strict=True)):
        dup[i] = (t, s) in seen
        seen.add((t, s))
    ms = ms[~dup]
    ms[:, 3] = wrap(ms[:, 3])
    dropped = {"robot_sightings": int(robot_rows.sum()), "unknown_barcodes": int(unknown.sum()),
               "unknown_landmarks": int(no_position.sum()), "duplicates": int(dup.sum())}
    sightings = np.empty((0, 4))
    if robot_sightings:
        sightings = _robot_sightings(all_rows[robot_rows & (subjects != robot)])
    return MrclamData(folder, robot, od, ms, gt, landmarks, barcodes, dropped, sightings)


def _robot_sightings(rows: np.ndarray) -> np.ndarray:
    """Rows ``t, subject, range, bearing`` of robot sightings: the first of a robot at one
    time stamp kept, bearings wrapped."""
    seen: set[tuple[float, int]] = set()
    keep = np.ones(len(rows), dtype=bool)
    for i, (t, s) in enumerate(zip(rows[:, 0].tolist(), rows[:, 1].astype(int).tolist(), strict=True)):
        keep[i] = (t, s) not in seen
        seen.add((t, s))
    out = rows[keep].copy()
    out[:, 3] = wrap(out[:, 3])
    return out
