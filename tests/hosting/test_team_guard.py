"""A team filter that fails anywhere is switched off with a message, the
other team filters and the simulation go on, and it gets no score (hosting/team_runner.py)."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import pytest

from beacon_sim.core.scenario import load_team_scenario
from beacon_sim.filters import team as team_filters
from beacon_sim.filters.team import IndependentTeam
from beacon_sim.hosting.team_runner import validate_team_estimates
from beacon_sim.runs.headless import run_headless

TEAM = Path(__file__).parents[2] / "scenarios" / "team" / "team_sparse.toml"


class _Broken(IndependentTeam):
    """The independent baseline with one fault, switched by ``how``."""

    how = ""

    def predict(self, controls, dt):
        if self.how == "raise" and self.ctx.dt > 0:
            raise ZeroDivisionError("boom")
        if self.how == "exit":
            sys.exit(0)
        if self.how == "hang":
            while True:
                time.sleep(0.001)
        super().predict(controls, dt)

    def estimates(self):
        est = super().estimates()
        if self.how == "nan":
            est[1] = (np.full(3, np.nan), est[1][1])
        if self.how == "short":
            est = est[:1]
        if self.how == "asym":
            c = est[2][1].copy()
            c[0, 1] += 1.0
            est[2] = (est[2][0], c)
        return est


def _make(how):
    return type(f"Broken_{how}", (_Broken,), {"how": how})


@pytest.fixture(scope="module")
def team():
    return load_team_scenario(TEAM)


@pytest.mark.parametrize("how, says", [("raise", "ZeroDivisionError: boom"),
                                       ("exit", "SystemExit(0)"),
                                       ("hang", "time limit"),
                                       ("nan", "robot 2: estimate() returned NaN"),
                                       ("short", "1 entries, expected one (mean, cov) pair per robot (3)"),
                                       ("asym", "robot 3: covariance is not symmetric")])
def test_a_failing_team_filter_is_switched_off_and_the_others_go_on(team, monkeypatch, how, says):
    monkeypatch.setitem(team_filters.TEAM_FILTERS, "broken", _make(how))
    res = run_headless(team, ["broken", "centralised"], seed=3, duration=2.0, step_limit_s=0.3)
    ref = run_headless(team, ["centralised"], seed=3, duration=2.0)
    assert says in (res.failed("broken") or "")
    assert res.failed("centralised") is None
    np.testing.assert_array_equal(np.array(res.tracks["centralised"].means),
                                  np.array(ref.tracks["centralised"].means))
    assert res.truth_checksum == ref.truth_checksum
    d = res.as_json()
    assert set(d["filters"]["broken"]) == {"failed"}  # no score for a failed filter
    assert d["filters"]["centralised"]["team_pos_rmse_m"] > 0


def test_a_team_filter_failing_to_build_is_reported(team, monkeypatch):
    def boom(ctx):
        raise RuntimeError("cannot build")
    monkeypatch.setitem(team_filters.TEAM_FILTERS, "broken", boom)
    res = run_headless(team, ["broken", "independent"], seed=1, duration=0.5)
    assert "could not be built: RuntimeError: cannot build" in res.failed("broken")
    assert len(res.tracks["independent"].means) == round(0.5 / team.dt)


def test_validate_team_estimates_checks_every_robot():
    good = (np.zeros(3), np.eye(3))
    means, covs = validate_team_estimates([good, good], 2)
    assert means.shape == (2, 3) and covs.shape == (2, 3, 3)
    assert "expected one (mean, cov) pair per robot (3)" in validate_team_estimates(good, 3)
    assert validate_team_estimates(good, 2).startswith("robot 1: estimate() returned ndarray")
    assert validate_team_estimates([good, (np.zeros(3), -np.eye(3))], 2).startswith("robot 2:")
    assert validate_team_estimates(None, 2).startswith("estimates() returned NoneType")


@pytest.mark.parametrize("setting, says", [
    ("centralised.gate_chi2=nan", "gate_chi2 = nan: expected a finite number"),
    ("decentralised.gate_chi2=-1", "gate_chi2 = -1: expected a number in [0, 1e+06]"),
    ("ci.gate_chi2=inf", "gate_chi2 = inf: expected a finite number"),
    ("ci.fusion=x", "fusion = 'x': expected 'ci' or 'naive'"),
])
def test_team_filter_parameters_have_ranges(setting, says, capsys):
    """The physical-range rule for every number a user types, on the team filters' --set too."""
    from beacon_sim.cli.main import main

    name = setting.split(".")[0]
    assert main(["run", "team_sparse", "--duration", "1", "--filter", name, "--set", setting]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and says in err[0]


@pytest.mark.parametrize("spec", ["independent:{evil}:Evil", "{evil}:Evil", "independent:evil_mod:Evil",
                                  "x=independent:../{evil}:Evil"])
def test_a_team_scenario_never_runs_code_it_names(tmp_path, spec, capsys):
    """Files are data on the team path too: a shared team scenario whose
    default_filters name a file or a module is refused before anything is imported."""
    from beacon_sim.cli.main import main

    marker = tmp_path / "ran"
    evil = tmp_path / "evil.py"
    evil.write_text(f"open({str(marker)!r}, 'w').write('x')\n"
                    "from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter as Evil\n")
    text = TEAM.read_text(encoding="utf-8")
    line = next(ln for ln in text.splitlines() if ln.startswith("default_filters"))
    spec = spec.format(evil=evil)
    bad = tmp_path / "t.toml"
    bad.write_text(text.replace(line, f"default_filters = [{spec!r}, 'centralised']"), encoding="utf-8")
    for cmd in (["run", str(bad), "--duration", "1"], ["eval", str(bad), "--runs", "1", "--duration", "1"],
                ["play", str(bad), "--frames", "1"]):
        assert main(cmd) == 2
        err = capsys.readouterr().err
        assert "default_filters[0]" in err and "may not name a file or module" in err
    assert not marker.exists()
