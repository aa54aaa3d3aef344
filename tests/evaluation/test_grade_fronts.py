"""The isolated host behind ``eval`` and ``check``, the
function form and the class choice, the CPU-time watchdog, and two more cases (a
huge but finite covariance, a filter raising KeyboardInterrupt in ``check``)."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest

from beacon_sim.cli.main import main
from beacon_sim.hosting.loading import load_filter_class
from beacon_sim.hosting.watchdog import FilterTimeout, time_limit

ATTACKS = Path(__file__).parents[1] / "attacks"

HUGE = """
import numpy as np
from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter


class Huge(ExtendedKalmanFilter):
    def estimate(self):
        mean, cov = super().estimate()
        return mean, cov * 1e300 + np.eye(3) * 1e307
"""

INTERRUPT = """
from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter


class Ki(ExtendedKalmanFilter):
    def update(self, measurements):
        super().update(measurements)
        if measurements:
            raise KeyboardInterrupt
"""


def _eval(capsys, *argv: str) -> dict:
    code = main(["eval", "default", "--runs", "2", "--duration", "3", "--json", *argv])
    assert code == 0
    return json.loads(capsys.readouterr().out)["filters"]


def test_eval_hosts_a_file_in_its_own_process_with_the_same_figures(capsys):
    honest = f"{ATTACKS / 'honest.py'}:MyEkf"
    inside = _eval(capsys, "--filter", honest, "--filter", "ekf", "--sandbox", "none")
    isolated = _eval(capsys, "--filter", honest, "--filter", "ekf")
    for name in ("MyEkf", "ekf"):
        for key in ("pos_rmse_m", "heading_rmse_rad", "anees", "rmse_over_pcrb"):
            assert inside[name][key] == isolated[name][key], (name, key)


def test_eval_blames_a_file_that_exits_and_goes_on(capsys):
    got = _eval(capsys, "--filter", str(ATTACKS / "os_exit.py"), "--filter", "ekf")
    assert got["os_exit"]["failed_runs"] == 2 and got["os_exit"]["pos_rmse_m"] is None
    assert "exited with status 3" in got["os_exit"]["failures"][0]["reason"]
    assert got["ekf"]["failed_runs"] == 0 and got["ekf"]["pos_rmse_m"] > 0


def test_a_huge_but_finite_covariance_is_a_failure_not_a_crash(tmp_path, capsys):
    path = tmp_path / "huge.py"
    path.write_text(HUGE)
    got = _eval(capsys, "--filter", f"{path}:Huge")
    assert got["Huge"]["failed_runs"] == 2 and "diverged" in got["Huge"]["failures"][0]["reason"]
    assert main(["check", f"{path}:Huge"]) == 1
    out = capsys.readouterr().out
    assert "FAIL  finite" in out and "diverged" in out


def test_check_reports_a_keyboard_interrupt_from_the_filter(tmp_path, capsys):
    path = tmp_path / "ki.py"
    path.write_text(INTERRUPT)
    assert main(["check", f"{path}:Ki"]) == 1  # not 130, not silent
    out = capsys.readouterr().out
    assert "FAIL  runs" in out and "KeyboardInterrupt raised by the filter" in out
    assert "in a process of its own" in out


def test_check_of_a_missing_file_is_one_line_and_status_2(capsys):
    assert main(["check", "/nonexistent/nosuch.py:X"]) == 2
    err = capsys.readouterr().err
    assert "no such filter file" in err and len(err.strip().splitlines()) == 1


def test_a_file_of_functions_is_a_filter_and_passes_check(capsys):
    assert main(["check", str(ATTACKS / "functions.py")]) == 0
    assert "13 of 13 checks passed" in capsys.readouterr().out
    cls = load_filter_class(f"{ATTACKS / 'functions.py'}:functions")
    assert cls.__name__ == "functions" and callable(cls.estimate)


def test_the_class_that_implements_the_interface_is_chosen():
    assert load_filter_class(str(ATTACKS / "helper_last.py")).__name__ == "MyEkf"


def test_a_cpu_time_limit_ignores_sleep_and_stops_a_busy_loop():
    with time_limit(0.1, cpu=True):  # 0.3 s of wall time, almost no CPU: no time-out
        time.sleep(0.3)
    t0 = time.monotonic()
    with pytest.raises(FilterTimeout), time_limit(0.1, cpu=True):
        while time.monotonic() - t0 < 60.0:  # generous: stopped long before, whatever the load
            pass
