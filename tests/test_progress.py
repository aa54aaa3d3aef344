"""Long work shows progress on stderr; short work prints nothing."""

from beacon_sim.core.scenario import load_scenario
from beacon_sim.runs import progress
from beacon_sim.runs.headless import run_headless


def test_short_work_prints_nothing(capsys):
    bar = progress.Progress(50, "run x", True, unit="ticks")
    for _ in range(50):
        bar.advance()
    assert capsys.readouterr().err == ""


def test_a_long_run_draws_a_bar_that_ends_at_the_total(capsys, monkeypatch):
    monkeypatch.setattr(progress, "SHOW_AFTER_S", 0.0)   # as if every tick took a long time
    monkeypatch.setattr(progress, "REDRAW_EVERY_S", 0.0)
    run_headless(load_scenario("default"), ["ekf"], duration=2.0, progress=True)
    err = capsys.readouterr().err
    assert "run default [" in err and err.rstrip().endswith("s")
    assert "40/40 ticks" in err and err.endswith("\n")


def test_disabled_prints_nothing(capsys, monkeypatch):
    monkeypatch.setattr(progress, "SHOW_AFTER_S", 0.0)
    run_headless(load_scenario("default"), ["ekf"], duration=2.0, progress=False)
    assert capsys.readouterr().err == ""
