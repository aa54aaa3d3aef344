"""MRCLAM: a synthetic folder in the real format (comment lines, CRLF, tabs, robot sightings,
unknown barcodes, repeated time stamps) loads, calibrates to the noise it was made with and
runs; malformed files name file and line; Dataset 6 (when present) gives a bounded error."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np
import pytest

from beacon_sim.cli.main import main
from beacon_sim.core.angles import wrap
from beacon_sim.io.mrclam import MrclamError, load_mrclam, read_table
from beacon_sim.runs.mrclam import calibrate, run_mrclam

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


def make_folder(folder: Path, seconds: float = 120.0, seed: int = 1) -> dict:
    """A robot driving around a 4 m square of landmarks; returns what was written."""
    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True, exist_ok=True)
    n = round(seconds / DT)
    t = T0 + DT * np.arange(n + 1)
    v_cmd = np.repeat(rng.uniform(0.05, 0.15, n // 200 + 1), 200)[:n]
    w_cmd = np.repeat(rng.uniform(-0.3, 0.3, n // 200 + 1), 200)[:n]
    pose = np.zeros((n + 1, 3))
    pose[0] = (2.0, 2.0, 0.3)
    for k in range(n):
        v = v_cmd[k] + V_STD * rng.standard_normal()
        w = w_cmd[k] + W_STD * rng.standard_normal()
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


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    f = tmp_path_factory.mktemp("mrclam") / "SyntheticSet"
    info = make_folder(f)
    return f, info


def test_synthetic_folder_loads_and_drops_what_it_must(folder):
    f, info = folder
    assert (f / "Robot1_Odometry.dat").read_bytes().count(b"\r\n") > 100
    d = load_mrclam(f, 1)
    assert d.dropped["robot_sightings"] == info["n_robot"]
    assert d.dropped["unknown_barcodes"] == info["n_unknown"]
    assert len(d.measurements) == info["n_meas"] - info["n_robot"] - info["n_unknown"]
    assert set(d.measurements[:, 1].astype(int)) <= set(LANDMARKS)
    assert np.all(np.diff(d.odometry[:, 0]) >= 0)
    # ground truth interpolates to the truth between samples, and is invalid outside it
    mid = info["t"][1000] + 0.004
    pose, ok = d.truth_at([mid, T0 - 10, info["t"][-1] + 5])
    assert ok.tolist() == [True, False, False]
    np.testing.assert_allclose(pose[0, :2], 0.6 * info["pose"][1000, :2] + 0.4 * info["pose"][1001, :2],
                               atol=1e-6)


def test_calibration_recovers_the_noise_the_data_was_made_with(folder):
    f, info = folder
    cal = calibrate(load_mrclam(f, 1))
    # the truth drew white velocity noise of V_STD, W_STD per 0.01 s step
    assert cal.step_dt == pytest.approx(DT, rel=1e-3)
    assert cal.motion.v_std == pytest.approx(V_STD, rel=0.2)
    assert cal.motion.omega_std == pytest.approx(W_STD, rel=0.2)
    # readings: robust statistics ignore the flipped bearings
    assert cal.sensor.range_std == pytest.approx(R_STD, rel=0.2)
    assert cal.sensor.bearing_std == pytest.approx(B_STD, rel=0.2)
    n_landmark_rows = info["n_meas"] - info["n_robot"] - info["n_unknown"]
    assert cal.stats["bearing_flipped"] == pytest.approx(info["n_flip"] / n_landmark_rows, abs=1e-9)


UNGATED_EKF = "beacon_sim.filters.ekf:ExtendedKalmanFilter"  # same filter, gate off by default


def test_filters_run_on_the_synthetic_folder(folder):
    f, _ = folder
    d = load_mrclam(f, 1)
    run = run_mrclam(d, ["ekf", "ukf", "dead_reckoning", UNGATED_EKF],
                     params={"ekf": {"gate_chi2": 13.8}})
    res = run.evaluate()
    assert run.updates == len(np.unique(d.measurements[:, 0]))
    for name in res:
        assert "failed" not in res[name]
    rmse = {k: v["pos_rmse_m"] for k, v in res.items()}
    # 4-5 landmarks in reach, 5 cm / 0.02 rad readings every 0.25 s: a gated EKF stays
    # within a few cm (measured 0.015 m); the 2 % of bearings flipped by pi are gated out
    assert rmse["ekf"] < 0.05
    assert res["ekf"]["rejected_readings"] >= 1
    # without a gate the flipped bearings pull both EKF and UKF off (measured 0.23 m each):
    # outlier handling matters, not the linearisation
    assert rmse["ukf"] > 3 * rmse["ekf"] and rmse["ExtendedKalmanFilter"] > 3 * rmse["ekf"]
    assert rmse["ExtendedKalmanFilter"] == pytest.approx(rmse["ukf"], rel=0.1)
    assert rmse["dead_reckoning"] > 3 * rmse["ekf"]


def test_predictions_reach_each_reading_time(folder):
    """A filter that records its predict calls sees the readings at their own time stamps."""
    f, _ = folder
    d = load_mrclam(f, 1)
    run = run_mrclam(d, ["dead_reckoning"], duration=10.0)
    tr = run.tracks["dead_reckoning"]
    times = np.array(tr.times)
    group_t = np.unique(d.measurements[:, 0])
    group_t = group_t[group_t <= d.t0 + 10.0]
    assert np.isin(group_t, times).all()
    assert times[-1] == pytest.approx(d.t0 + 10.0, abs=DT)


def test_cli_runs_and_prints_the_table(folder, capsys):
    f, _ = folder
    assert main(["mrclam", str(f), "--robot", "1", "--headless", "--filter", "ekf",
                 "--duration", "30", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["filters"]["ekf"]["pos_rmse_m"] < 0.2
    assert d["duration_s"] == pytest.approx(30.0, abs=0.02)
    assert main(["mrclam", str(f), "--robot", "1", "--calibrate"]) == 0
    assert "v_std" in capsys.readouterr().out


@pytest.mark.parametrize("name, line, error", [
    ("Robot1_Odometry.dat", "1248444200.000 \t 0.1\r\n", "expected 3 columns"),
    ("Robot1_Measurement.dat", "1248444200.000 \t 63 \t x.5 \t 0.1\r\n", "not a number"),
])
def test_malformed_file_names_file_and_line(folder, tmp_path, name, line, error, capsys):
    f, _ = folder
    bad = tmp_path / "bad"
    bad.mkdir()
    for p in f.iterdir():
        (bad / p.name).write_bytes(p.read_bytes())
    data = (bad / name).read_bytes().split(b"\r\n")
    data.insert(10, line.rstrip("\r\n").encode())
    (bad / name).write_bytes(b"\r\n".join(data))
    with pytest.raises(MrclamError, match=f"{name}:11: {error}"):
        load_mrclam(bad, 1)
    assert main(["mrclam", str(bad), "--robot", "1", "--headless"]) == 2
    err = capsys.readouterr().err.strip()
    assert f"{name}:11" in err and "\n" not in err


def test_missing_files_and_folders(tmp_path, folder):
    with pytest.raises(MrclamError, match="no such folder"):
        load_mrclam(tmp_path / "nope", 1)
    f, _ = folder
    with pytest.raises(MrclamError, match=r"Robot2_Odometry\.dat: missing"):
        load_mrclam(f, 2)
    with pytest.raises(MrclamError, match="expected 1 to 5"):
        load_mrclam(f, 7)
    empty = tmp_path / "e.dat"
    empty.write_text("# only\r\n# comments\r\n")
    with pytest.raises(MrclamError, match="no data rows"):
        read_table(empty, 3, "t, v, w")


def dataset6() -> Path | None:
    env = os.environ.get("BEACON_SIM_MRCLAM")
    candidates = [Path(env)] if env else []
    repo = Path(__file__).resolve().parents[1]
    candidates.append(repo.parent / "shared" / "data" / "mrclam" / "Dataset6")
    return next((c for c in candidates if (c / "Robot1_Odometry.dat").is_file()), None)


@pytest.mark.slow
@pytest.mark.skipif(dataset6() is None, reason="MRCLAM Dataset6 not found (set BEACON_SIM_MRCLAM)")
def test_dataset6_robot1_ekf_and_ukf_bounded():
    """First 300 s of robot 1. Measured (docs/replay.md): EKF and UKF position RMSE 0.21 m,
    dead reckoning 0.84 m. Bound 0.35 m: beats odometry alone by more than 2x, and sits at
    2.5x seed 001's full-run UKF figure (sqrt(0.0119 + 0.0078) = 0.14 m), room for
    calibration noise but not for a wrapped-bearing bug (seed 001's EKF: 1.9 m)."""
    d = load_mrclam(dataset6(), 1)
    res = run_mrclam(d, ["ekf", "ukf", "dead_reckoning"], duration=300.0).evaluate()
    for name in ("ekf", "ukf"):
        assert res[name]["pos_rmse_m"] < 0.35, res[name]
        assert res[name]["heading_rmse_rad"] < 0.25, res[name]
    assert res["dead_reckoning"]["pos_rmse_m"] > 2 * res["ekf"]["pos_rmse_m"]
    # with wrapped bearings the EKF is as good as the UKF (seed 001 found it 100x worse)
    assert res["ekf"]["pos_rmse_m"] < 1.2 * res["ukf"]["pos_rmse_m"]
