"""One MRCLAM run over N robots: a single robot is a team of one, run through
TeamRunner, and gives exactly what a straightforward loop over its odometry and readings
gives; a team run keeps its keys, and each robot's own filter run as ``independent:ekf``
(one FilterRunner per robot) equals the ``independent`` team filter."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from mrclam_helpers import COMMENT, make_folder

from beacon_sim.core.types import Control, Measurement
from beacon_sim.hosting.loading import build_filter, filter_names
from beacon_sim.io.mrclam import load_mrclam
from beacon_sim.runs.mrclam import MRCLAM_PARAMS, SENSOR_NAME, calibration_for, mrclam_scenario, run_mrclam


def _with_odometry_gap(folder: Path, start: int, stop: int) -> None:
    """Drop odometry rows ``start:stop`` (a gap of (stop - start) x 0.01 s the run must split)."""
    path = folder / "Robot1_Odometry.dat"
    lines = path.read_bytes().decode().split("\r\n")
    head = len(COMMENT.split("\r\n")) - 1
    path.write_bytes("\r\n".join(lines[:head + start] + lines[head + stop:]).encode())


def straightforward_run(data, specs, duration, cal, params):
    """The single-robot MRCLAM run written as plainly as possible: every filter built with
    the MRCLAM defaults, then for each time stamp in order (a reading group before an odometry
    row of the same stamp) predict with the command in force up to it, in equal steps of at
    most 1.5 odometry intervals, update if it is a reading group, take the odometry row's
    command (times the calibrated command scales) if it is one, and record every filter's
    estimate."""
    od, ms = data.odometry, data.measurements
    t0 = data.t0
    t_end = min(float(od[-1, 0]), t0 + duration)
    sc = mrclam_scenario(data, cal, t0, t_end)
    flts = {n: build_filter(s, sc, 0, name=n, params={**MRCLAM_PARAMS.get(s, {}), **params.get(n, {})})
            for n, s in zip(filter_names(specs), specs, strict=True)}
    out = {n: ([t0], [f.estimate()[0]], [f.estimate()[1]]) for n, f in flts.items()}
    events = [(t, 0, None) for t in np.unique(ms[(ms[:, 0] > t0) & (ms[:, 0] <= t_end), 0])]
    events += [(row[0], 1, row) for row in od[(od[:, 0] > t0) & (od[:, 0] <= t_end)]]
    events.sort(key=lambda e: (e[0], e[1]))  # stable: odometry rows keep their file order
    row0 = od[np.searchsorted(od[:, 0], t0, side="right") - 1]
    kv, kw = cal.v_scale, cal.omega_scale
    u, t = Control(row0[1] * kv, row0[2] * kw), t0
    for stamp, is_odometry, row in events:
        dt = stamp - t
        if dt > 0:
            n = max(1, math.ceil(dt / (1.5 * cal.step_dt) - 1e-9))
            for f in flts.values():
                for _ in range(n):
                    f.predict(u, dt / n)
        t = stamp
        if is_odometry:
            u = Control(float(row[1]) * kv, float(row[2]) * kw)
        else:
            rows = ms[ms[:, 0] == stamp]
            m = Measurement(SENSOR_NAME, "range_bearing", rows[:, 2:4].copy(), rows[:, 1].astype(int))
            for f in flts.values():
                f.update([m])
        for n, f in flts.items():
            mean, cov = f.estimate()
            out[n][0].append(t)
            out[n][1].append(mean)
            out[n][2].append(cov)
    return out


@pytest.fixture(scope="module")
def gapped(tmp_path_factory):
    f = tmp_path_factory.mktemp("gap") / "Set"
    make_folder(f, seconds=35.0, seed=5, drives=0.95)
    _with_odometry_gap(f, 500, 620)  # 1.2 s without odometry, readings every 0.25 s
    return load_mrclam(f, 1)


def test_a_single_robot_run_is_the_straightforward_loop(gapped):
    specs = ["ekf", "ukf", "pf", "dead_reckoning"]
    cal = calibration_for(gapped, "self")
    assert cal.v_scale != 1.0 and cal.inflation == 1.0  # the scales are used, nothing inflated
    run = run_mrclam(gapped, specs, duration=12.0, calibration=cal,
                     params={"pf": {"n_particles": 500}})
    assert run.team.solo and run.team.n_robots == 1 and run.scenario is run.team.robots[0].scenario
    want = straightforward_run(gapped, specs, 12.0, cal, {"pf": {"n_particles": 500}})
    assert np.diff(want["ekf"][0]).max() > 10 * cal.step_dt  # the gap is there: split in steps
    for n in filter_names(specs):
        tr = run.tracks[n]
        assert tr.failed is None
        np.testing.assert_array_equal(tr.times, np.array(want[n][0]))
        np.testing.assert_array_equal(tr.means, np.array(want[n][1]))
        np.testing.assert_array_equal(tr.covs, np.array(want[n][2]))
    assert run.updates == len(np.unique(gapped.measurements[(gapped.measurements[:, 0] > gapped.t0)
                                                             & (gapped.measurements[:, 0] <= run.t_end), 0]))


def _two_robot_folder(base: Path) -> Path:
    one, two = base / "a", base / "b"
    make_folder(one, seconds=30.0, seed=1)
    make_folder(two, seconds=30.0, seed=2)
    for kind in ("Groundtruth", "Odometry", "Measurement"):
        shutil.copy(two / f"Robot1_{kind}.dat", one / f"Robot2_{kind}.dat")
    return one


def test_a_team_run_keeps_its_keys_and_its_own_filters_agree(tmp_path):
    f = _two_robot_folder(tmp_path)
    robots = [load_mrclam(f, r, robot_sightings=True) for r in (1, 2)]
    run = run_mrclam(robots, ["independent", "independent:ekf", "centralised"], duration=20.0)
    assert not run.team.solo and run.team.ids == (1, 2)
    d = run.as_json()
    assert {"dataset", "robots", "duration_s", "landmark_readings", "robot_sightings", "filters",
            "us_per_step", "wall_s", "failed"} <= set(d)
    assert d["robots"] == [1, 2] and d["failed"] == {}
    assert set(d["filters"]) == {"independent", "independent:ekf", "centralised"}
    for rows in d["filters"].values():
        assert set(rows) == {"1", "2"}
        for row in rows.values():
            assert {"pos_rmse_m", "anees", "mse_x", "nees_above_99"} <= set(row)
    # each robot's own EKF, as one FilterRunner per robot or as the team filter: the same
    for i in range(2):
        a, b = run.robot_tracks[i]["independent"], run.robot_tracks[i]["independent:ekf"]
        assert a.joint and not b.joint
        np.testing.assert_array_equal(a.times, b.times)
        np.testing.assert_allclose(a.means, b.means, rtol=0, atol=1e-12)
        np.testing.assert_allclose(a.covs, b.covs, rtol=0, atol=1e-12)
    # the team's noise comes from the other robot by default, as a single robot's does
    assert "robot 2" in run.calibrations[0].source and "robot 1" in run.calibrations[1].source


def test_a_failing_filter_is_switched_off_with_no_score_alone_or_in_a_team(tmp_path):
    f = _two_robot_folder(tmp_path)
    code = tmp_path / "flaky.py"
    code.write_text(
        "from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter\n"
        "class Flaky(ExtendedKalmanFilter):\n"
        "    calls = 0\n"
        "    def update(self, ms):\n"
        "        Flaky.calls += 1\n"
        "        if Flaky.calls > 20:\n"
        "            raise RuntimeError('breaks on its 21st update')\n"
        "        super().update(ms)\n")
    alone = run_mrclam(load_mrclam(f, 1), ["ekf", f"{code}:Flaky"], duration=20.0)
    rows = alone.evaluate()
    assert "21st update" in rows["Flaky"]["failed"] and rows["Flaky"]["pos_rmse_m"] is None
    assert 0 < rows["Flaky"]["failed_time_s"] < 20.0
    assert "failed" not in rows["ekf"] and rows["ekf"]["pos_rmse_m"] < 0.2
    tr = alone.tracks["Flaky"]
    assert 0 < len(tr.times) < len(alone.tracks["ekf"].times)  # its estimates before it failed
    team = run_mrclam([load_mrclam(f, r, robot_sightings=True) for r in (1, 2)],
                      ["independent", f"independent:{code}:Flaky"], duration=20.0).as_json()
    assert set(team["filters"]) == {"independent"}
    assert "21st update" in team["failed"][f"independent:{code}:Flaky"]
