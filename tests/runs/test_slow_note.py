"""A run that costs more than SLOW_CPU_PER_SIM_S seconds of CPU per simulated second says
so once, naming what costs it (run), or the filter (eval). The threshold is lowered here so
that a short run of a particle filter beside an EKF crosses it; the note must name the
particle filter (2,000 particles, about 1 ms a step; the EKF about 0.02 ms)."""

from __future__ import annotations

from beacon_sim.cli.main import main
from beacon_sim.core.scenario import load_scenario
from beacon_sim.runs import headless


def test_run_says_once_which_filter_makes_it_slow(monkeypatch):
    monkeypatch.setattr(headless, "SLOW_CPU_PER_SIM_S", 1e-6)
    monkeypatch.setattr(headless, "SLOW_JUDGED_AFTER_CPU_S", 0.02)
    lines: list[str] = []
    headless.run_headless(load_scenario("default"), ["ekf", "pf"], seed=3, duration=10.0,
                          params={"pf": {"n_particles": 2000}}, on_slow=lines.append)
    assert len(lines) == 1
    assert lines[0].startswith("note: filter pf costs ") and "of CPU per simulated second" in lines[0]


def test_a_fast_run_says_nothing():
    lines: list[str] = []
    headless.run_headless(load_scenario("default"), ["ekf"], seed=3, duration=3.0, on_slow=lines.append)
    assert lines == []


def test_eval_says_it_once_on_stderr(monkeypatch, capsys):
    import beacon_sim.cli.eval as cli_eval

    monkeypatch.setattr(cli_eval, "SLOW_CPU_PER_SIM_S", 1e-6)
    assert main(["eval", "default", "--runs", "3", "--duration", "1", "--filter", "ekf", "--json"]) == 0
    err = [line for line in capsys.readouterr().err.splitlines() if line.startswith("note:")]
    assert len(err) == 1 and "filter ekf costs" in err[0] and "of filter time" in err[0]
