"""``beacon-sim new-filter --tdoa``: the TDOA template is written, passes ``check`` on
ruiz_ulps, tracks about as well as the built-in EKF with its own (naive) R as written, and
with TODO 1 done (the correlated R) it is the built-in EKF told the truth."""

from __future__ import annotations

import numpy as np
import pytest

from beacon_sim.cli.main import main
from beacon_sim.core.scenario import load_scenario
from beacon_sim.runs.headless import run_headless


@pytest.fixture
def tdoa_file(tmp_path, capsys):
    path = tmp_path / "my_tdoa.py"
    assert main(["new-filter", str(path), "--tdoa"]) == 0
    out = capsys.readouterr().out
    assert "MyTdoa" in out and "--scenario ruiz_ulps" in out and "play ulps_leave" in out
    return path


def test_template_passes_check_on_ruiz_ulps(tdoa_file, capsys):
    code = main(["check", f"{tdoa_file}:MyTdoa", "--scenario", "ruiz_ulps"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "FAIL" not in out


def _errors(res, name):
    truth = np.asarray(res.true_poses).reshape(-1, 3)[-len(res.tracks[name].means):]
    est = np.asarray(res.tracks[name].means)
    return np.hypot(*(est[:, :2] - truth[:, :2]).T)


def test_template_as_it_is_and_with_todo_1_done(tdoa_file, tmp_path):
    sc = load_scenario("ulps_leave")
    res = run_headless(sc, [f"{tdoa_file}:MyTdoa", "ekf", "dead_reckoning"], seed=3, duration=60.0)
    mine, ekf, dr = (_errors(res, n) for n in ("MyTdoa", "ekf", "dead_reckoning"))
    rms = {k: float(np.sqrt(np.mean(v**2))) for k, v in (("mine", mine), ("ekf", ekf), ("dr", dr))}
    assert rms["mine"] < 1.3 * rms["ekf"] and rms["mine"] < 0.05, rms
    done = tmp_path / "done.py"
    done.write_text(tdoa_file.read_text().replace(
        "            R = 2.0 * s * s * np.eye(k)\n",
        "            R = s * s * (np.eye(k) + np.ones((k, k)))\n"))
    res2 = run_headless(sc, [f"{done}:MyTdoa", "ekf"], seed=3, duration=60.0)
    a, b = np.asarray(res2.tracks["MyTdoa"].means), np.asarray(res2.tracks["ekf"].means)
    assert np.allclose(a, b, atol=1e-6)                # the built-in EKF, to rounding
    assert not np.allclose(np.asarray(res.tracks["MyTdoa"].means), b, atol=1e-4)  # naive differs
