"""MRCLAM calibration not fitted on the scored run: leave-one-robot-out by
default, the source printed, the fitted-on-itself mode labelled."""

from __future__ import annotations

import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from mrclam_helpers import make_folder

from beacon_sim.io.mrclam import load_mrclam
from beacon_sim.runs.mrclam import calibration_for, inflated, leave_one_robot_out, run_mrclam, told_inflated


def _two_robots(base: Path, name: str, shift_robot1_truth: float = 0.0, seconds: float = 60.0) -> Path:
    """A folder with robot 1 (seed 1) and robot 2 (another drive, seed 2); robot 1's ground
    truth optionally shifted by ``shift`` [m] in x (what leave-one-robot-out must not see)."""
    one, two = base / f"{name}_a", base / f"{name}_b"
    make_folder(one, seconds=seconds, seed=1)
    make_folder(two, seconds=seconds, seed=2)
    for kind in ("Groundtruth", "Odometry", "Measurement"):
        shutil.copy(two / f"Robot1_{kind}.dat", one / f"Robot2_{kind}.dat")
    if shift_robot1_truth:
        path = one / "Robot1_Groundtruth.dat"
        lines = []
        for line in path.read_text().splitlines():
            if line.startswith("#") or not line.strip():
                lines.append(line)
                continue
            t, x, y, th = (float(v) for v in line.split())
            lines.append(f"{t:.3f} \t {x + shift_robot1_truth:.8f} \t {y:.8f} \t {th:.8f}")
        path.write_text("\n".join(lines) + "\n")
    return one


def test_leave_one_robot_out_never_reads_the_scored_runs_ground_truth(tmp_path):
    clean = load_mrclam(_two_robots(tmp_path, "clean"), 1)
    noisy = load_mrclam(_two_robots(tmp_path, "moved", shift_robot1_truth=0.3), 1)
    a, b = leave_one_robot_out(clean), leave_one_robot_out(noisy)
    assert "robot 2" in a.source and "not on the scored run" in a.source
    # robot 1's ground truth moved by 30 cm: the noise from the other robot is the same
    assert (a.motion.v_std, a.motion.omega_std, a.sensor.range_std, a.sensor.bearing_std) == \
        (b.motion.v_std, b.motion.omega_std, b.sensor.range_std, b.sensor.bearing_std)
    # while the fitted-on-itself calibration sees it (the range residuals grow)
    sa, sb = calibration_for(clean, "self"), calibration_for(noisy, "self")
    assert sb.sensor.range_std > 1.5 * sa.sensor.range_std
    assert "own ground truth" in sa.source


def test_run_mrclam_calibrates_from_the_other_robots_by_default(tmp_path):
    d = load_mrclam(_two_robots(tmp_path, "run"), 1)
    run = run_mrclam(d, ["ekf"], duration=20.0)
    assert "other runs" in run.calibration.source
    assert run.as_json()["calibration_source"] == run.calibration.source
    row = run.evaluate()["ekf"]
    assert 0.0 <= row["nees_above_99"] <= 1.0 and row["largest_jump_m"] >= 0.0


def test_a_folder_with_one_robot_falls_back_and_says_so(tmp_path):
    f = tmp_path / "single"
    make_folder(f, seconds=30.0)
    cal = leave_one_robot_out(load_mrclam(f, 1))
    assert "no other robot" in cal.source and "own ground truth" in cal.source


@pytest.mark.slow
@pytest.mark.parametrize("robot", [1, 2, 3, 4, 5])
def test_dataset6_goals_with_calibration_from_the_other_robots(robot, mrclam_dataset6):
    """The MRCLAM goals (docs/results.md) on every robot of Dataset 6, the noise from the four others (the
    figures: docs/results.md, `python scripts/make_results.py --only mrclam`)."""
    run = run_mrclam(load_mrclam(mrclam_dataset6, robot), ["ekf", "ukf", "pf"])
    assert "not on the scored run" in run.calibration.source and run.calibration.inflation > 1.0
    for name, row in run.evaluate().items():
        assert row["pos_rmse_m"] <= 0.26, (name, row)
        assert 1.5 <= row["anees"] <= 6, (name, row)
        assert row["nees_above_99"] <= 0.05, (name, row)
    assert run.evaluate()["pf"]["largest_jump_m"] <= 1.0


def _three_robots(base: Path, name: str, shift_robot1_truth: float = 0.0) -> Path:
    """``_two_robots`` with a third robot (another drive, seed 3)."""
    one = _two_robots(base, name, shift_robot1_truth, seconds=25.0)
    three = base / f"{name}_c"
    make_folder(three, seconds=25.0, seed=3)
    for kind in ("Groundtruth", "Odometry", "Measurement"):
        shutil.copy(three / f"Robot1_{kind}.dat", one / f"Robot3_{kind}.dat")
    return one


def test_the_inflation_comes_from_the_held_out_robots_only(tmp_path):
    clean = leave_one_robot_out(load_mrclam(_three_robots(tmp_path, "c"), 1))
    moved = leave_one_robot_out(load_mrclam(_three_robots(tmp_path, "m", shift_robot1_truth=0.3), 1))
    assert clean.inflation >= 1.0 and "robot 2, robot 3" in clean.source
    assert clean.inflation == moved.inflation  # robot 1's ground truth is never read
    assert (clean.motion, clean.sensor, clean.v_scale) == (moved.motion, moved.sensor, moved.v_scale)
    # fewer than two robots held out: nothing to check the noise on, no inflation
    assert leave_one_robot_out(load_mrclam(_two_robots(tmp_path, "two", seconds=12.0), 1)).inflation == 1.0


def test_gaussian_filters_are_told_the_inflated_noise_the_robust_ones_the_pooled(tmp_path):
    d = load_mrclam(_two_robots(tmp_path, "route", seconds=12.0), 1)
    cal = replace(calibration_for(d, "self"), inflation=2.0)
    assert told_inflated("ekf") and told_inflated("a=ukf") and told_inflated("independent:ekf")
    assert not told_inflated("pf") and not told_inflated("histogram") and not told_inflated("independent:pf")
    few = {"pf": {"n_particles": 300}}
    both = run_mrclam(d, ["ekf", "pf"], duration=10.0, calibration=cal, params=few)
    ekf = run_mrclam(d, ["ekf"], duration=10.0, calibration=inflated(cal))
    pf = run_mrclam(d, ["pf"], duration=10.0, calibration=replace(cal, inflation=1.0), params=few)
    np.testing.assert_array_equal(both.tracks["ekf"].covs, ekf.tracks["ekf"].covs)
    np.testing.assert_array_equal(both.tracks["pf"].means, pf.tracks["pf"].means)
    assert inflated(cal).sensor.range_std == pytest.approx(cal.sensor.range_std * np.sqrt(2.0))
    assert list(both.tracks) == ["ekf", "pf"]
