"""A small synthetic MRCLAM folder (a robot driving around a 4 m square of landmarks), for the
MRCLAM reader and run tests and the window tests that play one."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from beacon_sim.core.angles import wrap
from beacon_sim.io.mrclam import read_table

COMMENT = ("# UTIAS Multi-Robot Cooperative Localization and Mapping Dataset\r\n"
           "# produced by a test\r\n# {what} Data Fomat:\r\n# {cols}\r\n")
LANDMARKS = {6: (0.0, 0.0), 7: (4.0, 0.0), 8: (4.0, 4.0), 9: (0.0, 4.0), 10: (2.0, -1.0)}
BARCODES = {1: 5, 2: 14, 3: 41, 4: 32, 5: 23, 6: 63, 7: 81, 8: 7, 9: 70, 10: 45}
T0 = 1248444187.0
DT = 0.01
V_STD, W_STD = 0.05, 0.1          # per 0.01 s step: the truth's velocity noise
R_STD, B_STD = 0.05, 0.02         # the readings' noise


def write_dat(path: Path, what: str, cols: str, rows, fmt: str) -> None:
    text = COMMENT.format(what=what, cols=cols)
    text += "".join(fmt.format(*r) + " \r\n" for r in rows)
    path.write_bytes(text.encode("ascii"))


def make_folder(folder: Path, seconds: float = 120.0, seed: int = 1, drives: float = 1.0) -> dict:
    """A robot driving around a 4 m square of landmarks, ``drives`` times what its odometry
    commands say; returns what was written."""
    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True, exist_ok=True)
    n = round(seconds / DT)
    t = T0 + DT * np.arange(n + 1)
    v_cmd = np.repeat(rng.uniform(0.05, 0.15, n // 200 + 1), 200)[:n]
    w_cmd = np.repeat(rng.uniform(-0.3, 0.3, n // 200 + 1), 200)[:n]
    pose = np.zeros((n + 1, 3))
    pose[0] = (2.0, 2.0, 0.3)
    for k in range(n):
        v = drives * v_cmd[k] + V_STD * rng.standard_normal()
        w = drives * w_cmd[k] + W_STD * rng.standard_normal()
        x, y, th = pose[k]
        pose[k + 1] = (x + v * DT * math.cos(th), y + v * DT * math.sin(th), wrap(th + w * DT))
    # ground truth from 3 s before the odometry; odometry with a repeated time stamp
    gt_t = np.concatenate([T0 - 3 + DT * np.arange(300), t])
    gt = np.column_stack([gt_t, np.vstack([np.tile(pose[0], (300, 1)), pose])])
    od = [(t[k], v_cmd[k], w_cmd[k]) for k in range(n)]
    od.insert(501, (t[500], v_cmd[500], w_cmd[500]))  # same stamp twice, same command
    # readings every 0.25 s of two landmarks at one stamp, plus noise rows
    meas, n_robot, n_unknown, n_flip = [], 0, 0, 0
    for k in range(25, n, 25):
        for s in (6 + (k // 25) % 5, 6 + (k // 25 + 2) % 5):
            lx, ly = LANDMARKS[s]
            x, y, th = pose[k]
            r = math.hypot(lx - x, ly - y) + R_STD * rng.standard_normal()
            b = wrap(math.atan2(ly - y, lx - x) - th + B_STD * rng.standard_normal())
            if k % 1000 == 0:  # a bearing off by pi, as in the real data
                b = wrap(b + math.pi)
                n_flip += 1
            meas.append((t[k], BARCODES[s], r, b))
        if k % 100 == 0:
            meas.append((t[k], 14, 1.5, 0.1))   # robot 2 seen
            n_robot += 1
        if k % 300 == 0:
            meas.append((t[k], 99, 2.0, 0.0))   # a barcode not in Barcodes.dat
            n_unknown += 1
    write_dat(folder / "Barcodes.dat", "Barcode", "Subject #    Barcode #",
              sorted(BARCODES.items()), "  {:d} \t  {:d}")
    write_dat(folder / "Landmark_Groundtruth.dat", "Landmark Groundtruth",
              "Subject #    x [m]    y [m]    x std-dev [m]    y std-dev [m]",
              [(s, x, y, 1e-4, 1e-4) for s, (x, y) in LANDMARKS.items()],
              "  {:d} \t {:.8f} \t {:.8f} \t {:.8f} \t {:.8f}")
    write_dat(folder / "Robot1_Groundtruth.dat", "Robot Groundtruth", "Time [s]    x [m]    y [m]",
              gt, "{:.3f} \t {:.8f} \t {:.8f} \t {:.8f}")
    write_dat(folder / "Robot1_Odometry.dat", "Odometry", "Time [s]    v    w", od,
              "{:.3f} \t  {:.6f} \t {:.6f}")
    write_dat(folder / "Robot1_Measurement.dat", "Measurement", "Time [s]    Subject #    r    b",
              meas, "{:.3f} \t  {:d} \t  {:.6f} \t {:.6f}")
    return {"n_robot": n_robot, "n_unknown": n_unknown, "n_flip": n_flip, "n_meas": len(meas),
            "pose": pose, "t": t}


def surveyed_landmarks(folder: Path) -> np.ndarray:
    """The landmarks' surveyed positions (x, y) [m], read straight from the file."""
    table = read_table(folder / "Landmark_Groundtruth.dat", 5, "subject x y sx sy")
    return table[table[:, 0] > 5][:, 1:3]
