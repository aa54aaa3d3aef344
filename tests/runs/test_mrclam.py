"""MRCLAM: a synthetic folder in the real format (comment lines, CRLF, tabs, robot sightings,
unknown barcodes, repeated time stamps) loads, calibrates to the noise it was made with and
runs; malformed files name file and line; Dataset 6 (when present) gives a bounded error."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from mrclam_helpers import B_STD, BARCODES, DT, LANDMARKS, R_STD, T0, V_STD, W_STD, make_folder, write_dat

from beacon_sim.cli.main import main
from beacon_sim.core.angles import wrap
from beacon_sim.io.mrclam import MRCLAM_VARIABLE, MrclamError, find_dataset, load_mrclam, read_table
from beacon_sim.runs.mrclam import calibrate, run_mrclam


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
    # honest: not below the noise's RMS (beyond sampling noise), and not wildly above it
    # (the shared-error factor of white readings is 1 plus sampling noise)
    assert 0.9 * R_STD < cal.sensor.range_std < 1.5 * R_STD
    assert 0.9 * B_STD < cal.sensor.bearing_std < 1.5 * B_STD
    n_landmark_rows = info["n_meas"] - info["n_robot"] - info["n_unknown"]
    assert cal.stats["bearing_flipped"] == pytest.approx(info["n_flip"] / n_landmark_rows, abs=1e-9)
    # the robot drives what it is commanded
    assert cal.v_scale == pytest.approx(1.0, abs=0.03) and cal.omega_scale == pytest.approx(1.0, abs=0.05)


def test_calibration_finds_the_command_scale_and_removes_it_from_the_noise(tmp_path):
    """A robot that drives 0.9 x its commands: the scale is found, and the noise told is the
    white noise around the scaled commands, not the drift the scale error would add."""
    make_folder(tmp_path / "Slow", seed=3, drives=0.9)
    cal = calibrate(load_mrclam(tmp_path / "Slow", 1))
    assert cal.v_scale == pytest.approx(0.9, abs=0.03)
    assert cal.omega_scale == pytest.approx(0.9, abs=0.05)
    assert cal.motion.v_std == pytest.approx(V_STD, rel=0.25)
    assert cal.motion.omega_std == pytest.approx(W_STD, rel=0.25)


UNGATED_EKF = "beacon_sim.filters.gaussian.ekf:ExtendedKalmanFilter"  # same filter, no MRCLAM defaults
#: Its gate off explicitly: a sensor that declares outliers (MRCLAM's calibrated rate) turns
#: the EKF's gate on by default.
UNGATED = {"ExtendedKalmanFilter": {"gate_chi2": 0.0}}


def test_filters_run_on_the_synthetic_folder(folder):
    f, info = folder
    d = load_mrclam(f, 1)
    run = run_mrclam(d, ["ekf", "ukf", "pf", "dead_reckoning", UNGATED_EKF], params=UNGATED)
    res = run.evaluate()
    assert run.updates == len(np.unique(d.measurements[:, 0]))
    for name in res:
        assert "failed" not in res[name]
    rmse = {k: v["pos_rmse_m"] for k, v in res.items()}
    # 4-5 landmarks in reach, 5 cm / 0.02 rad readings every 0.25 s: the gated EKF and UKF
    # (MRCLAM runs gate by default) and the PF with its outlier mixture stay within a few cm;
    # every bearing flipped by pi is gated out
    for name in ("ekf", "ukf", "pf"):
        assert rmse[name] < 0.05, (name, rmse)
    assert res["ekf"]["rejected_readings"] >= info["n_flip"]
    # without a gate the flipped bearings pull the EKF off (measured 0.23 m)
    assert rmse["ExtendedKalmanFilter"] > 3 * rmse["ekf"]
    assert rmse["dead_reckoning"] > 3 * rmse["ekf"]


def test_the_gate_rejects_an_injected_pi_flipped_bearing(folder):
    """One reading whose bearing is turned by pi: the gated EKF and UKF drop it and keep
    their belief; without the gate the EKF's heading is dragged off."""
    from beacon_sim.core.types import Measurement
    from beacon_sim.filters.base import GaussianBelief
    from beacon_sim.hosting.loading import build_filter
    from beacon_sim.runs.mrclam import MRCLAM_GATE_CHI2, mrclam_scenario

    f, info = folder
    d = load_mrclam(f, 1)
    cal = calibrate(d)
    sc = mrclam_scenario(d, cal, d.t0, d.t0 + 60.0)
    pose = info["pose"][0]
    lx, ly = LANDMARKS[8]
    r = math.hypot(lx - pose[0], ly - pose[1])
    b = wrap(math.atan2(ly - pose[1], lx - pose[0]) - pose[2])
    flipped = Measurement("camera", "range_bearing", np.array([[r, wrap(b + math.pi)]]), np.array([8]))
    moved = {}
    for name, gate in (("ekf", MRCLAM_GATE_CHI2), ("ukf", MRCLAM_GATE_CHI2), ("ekf", 0.0)):
        flt = build_filter(name, sc, seed=0, name=name, params={"gate_chi2": gate})
        flt.reset(GaussianBelief(np.array(pose), np.diag([0.05, 0.05, 0.05]) ** 2))
        flt.update([flipped])
        mean, _ = flt.estimate()
        moved[(name, gate)] = abs(wrap(mean[2] - pose[2]))
    assert moved[("ekf", MRCLAM_GATE_CHI2)] == 0.0
    assert moved[("ukf", MRCLAM_GATE_CHI2)] == 0.0
    assert moved[("ekf", 0.0)] > 0.05


def test_calibration_of_heavy_tailed_readings_is_honest(tmp_path):
    """Readings with Student-t noise (3 dof: RMS 1.7x the MAD-based spread): the told
    standard deviations reach the RMS of the noise, not its robust core."""
    rng = np.random.default_rng(3)
    folder = tmp_path / "HeavyTails"
    info = make_folder(folder, seconds=240.0, seed=4)
    meas = load_mrclam(folder, 1).measurements
    dof = 3
    tr = rng.standard_t(dof, len(meas)) * R_STD / math.sqrt(dof / (dof - 2))   # RMS R_STD
    tb = rng.standard_t(dof, len(meas)) * B_STD / math.sqrt(dof / (dof - 2))
    pose, _ = load_mrclam(folder, 1).truth_at(meas[:, 0])
    lxy = np.array([LANDMARKS[int(s)] for s in meas[:, 1]])
    r = np.hypot(lxy[:, 0] - pose[:, 0], lxy[:, 1] - pose[:, 1]) + tr
    b = wrap(np.arctan2(lxy[:, 1] - pose[:, 1], lxy[:, 0] - pose[:, 0]) - pose[:, 2] + tb)
    rows = [(t, BARCODES[int(s)], ri, bi) for t, s, ri, bi in zip(meas[:, 0], meas[:, 1], r, b, strict=True)]
    write_dat(folder / "Robot1_Measurement.dat", "Measurement", "Time [s]    Subject #    r    b",
              rows, "{:.3f} \t  {:d} \t  {:.6f} \t {:.6f}")
    cal = calibrate(load_mrclam(folder, 1))
    # honest: not below the noise's RMS (beyond sampling noise), and not wildly above it
    # (the shared-error factor of white readings is 1 plus sampling noise)
    assert 0.9 * R_STD < cal.sensor.range_std < 1.5 * R_STD
    assert 0.9 * B_STD < cal.sensor.bearing_std < 1.5 * B_STD
    # the robust spread alone would have told about 0.6x: overconfident
    assert cal.stats["range_err_robust_std_m"] < 0.8 * R_STD
    assert cal.stats["bearing_err_robust_std_rad"] < 0.8 * B_STD
    assert info["n_flip"] >= 0


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


def test_one_home_finds_the_data_set(tmp_path, folder, monkeypatch, capsys):
    """find_dataset: a data set's folder as it is; a folder holding MRCLAM_Dataset6 (or
    Dataset6) gives that one; nothing given: $BEACON_SIM_MRCLAM, and the command line without
    DIR reads it; none: one line naming the variable and DIR. Outputs name the data set by
    its folder's name, never where it is."""
    f, _ = folder
    root = tmp_path / "mrclam"
    six = root / "MRCLAM_Dataset6"
    six.mkdir(parents=True)
    (root / "Dataset2").mkdir()
    for p in f.iterdir():
        (six / p.name).write_bytes(p.read_bytes())
    assert find_dataset(f) == f and find_dataset(str(root)) == six
    assert find_dataset(root, 2) == root / "Dataset2"
    monkeypatch.setenv(MRCLAM_VARIABLE, str(root))
    assert find_dataset() == six and load_mrclam(None, 1).folder == six
    assert main(["mrclam", "--robot", "1", "--headless", "--filter", "dead_reckoning",
                 "--duration", "5", "--json"]) == 0
    out = capsys.readouterr().out
    assert json.loads(out)["dataset"] == "MRCLAM_Dataset6" and str(tmp_path) not in out
    assert main(["mrclam", "--robot", "1", "--calibrate", "--json"]) == 0
    out = capsys.readouterr().out
    assert json.loads(out)["dataset"] == "MRCLAM_Dataset6" and str(tmp_path) not in out
    (tmp_path / "empty").mkdir()
    for where, says in [("", "no MRCLAM data set given"),
                        (str(tmp_path / "nowhere"), r"nowhere \(from BEACON_SIM_MRCLAM\): no such folder"),
                        (str(tmp_path / "empty"), "neither an MRCLAM data set")]:
        monkeypatch.setenv(MRCLAM_VARIABLE, where)
        with pytest.raises(MrclamError, match=says):
            find_dataset()
        assert main(["mrclam", "--robot", "1", "--headless"]) == 2
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and "BEACON_SIM_MRCLAM" in err and "beacon-sim mrclam DIR" in err, err


@pytest.mark.slow
def test_dataset6_robot1_ekf_and_ukf_bounded(mrclam_dataset6, mrclam_calibration):
    """First 300 s of robot 1 with the default MRCLAM settings: EKF and UKF beat odometry
    alone by more than 2x, stay within 0.3 m and agree (seed 001 found its EKF 100x worse)."""
    d = load_mrclam(mrclam_dataset6, 1)
    cal = mrclam_calibration(d)  # the default's, computed once a session
    assert "not on the scored run" in cal.source and cal.inflation > 1.0
    res = run_mrclam(d, ["ekf", "ukf", "dead_reckoning"], duration=300.0, calibration=cal).evaluate()
    for name in ("ekf", "ukf"):
        assert res[name]["pos_rmse_m"] < 0.3, res[name]
        assert res[name]["heading_rmse_rad"] < 0.25, res[name]
    assert res["dead_reckoning"]["pos_rmse_m"] > 2 * res["ekf"]["pos_rmse_m"]
    assert res["ekf"]["pos_rmse_m"] < 1.2 * res["ukf"]["pos_rmse_m"]


@pytest.mark.slow
def test_dataset6_robot3_stays_under_0_3_m_and_honest(mrclam_dataset6, mrclam_calibration):
    """Robot 3, the whole run: its few bearings off by pi dragged the ungated EKF to 0.71 m
    (ANEES 3251). Calibrated noise and the gate: measured EKF 0.159 m, ANEES 4.4."""
    d = load_mrclam(mrclam_dataset6, 3)
    cal = mrclam_calibration(d)  # the default's, computed once a session
    assert "not on the scored run" in cal.source and cal.inflation > 1.0
    run = run_mrclam(d, ["ekf"], calibration=cal)
    res = run.evaluate()["ekf"]
    assert res["pos_rmse_m"] < 0.3, res
    assert 1.5 < res["anees"] < 6.0, res
    assert res["rejected_readings"] >= 4  # the flipped bearings


@pytest.mark.slow
def test_dataset6_robot3_particle_filter_does_not_jump(mrclam_dataset6, mrclam_calibration):
    """The particle filter on the first 200 s of robot 3: no jump of its estimate beyond 1 m
    (it jumped by metres with augmented-MCL injection and overconfident noise)."""
    d = load_mrclam(mrclam_dataset6, 3)
    run = run_mrclam(d, ["pf"], duration=200.0, params={"pf": {"n_particles": 1000}},
                     calibration=mrclam_calibration(d))  # the default's, computed once a session
    m = np.array(run.tracks["pf"].means)
    assert np.max(np.hypot(*np.diff(m[:, :2], axis=0).T)) < 1.0
    assert run.evaluate()["pf"]["pos_rmse_m"] < 0.3
