"""Isolation: a filter that raises, returns NaN / infinity / wrong shapes / a covariance that
is not symmetric PSD is switched off with a message; the run keeps stepping the others, whose
results are exactly those of a run without it. A slow filter gets a warning."""

from __future__ import annotations

import json
import textwrap
import time

import numpy as np
import pytest

from beacon_sim.cli.main import main
from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.hosting import runner as isolation
from beacon_sim.hosting.loading import build_filter
from beacon_sim.hosting.runner import FilterRunner, FilterTrack
from beacon_sim.runs.headless import run_headless

FAIL_AT = 5   # faulty filters misbehave on their 5th step

FAULTY = textwrap.dedent("""
    import time
    import numpy as np
    from beacon_sim.filters.gaussian.dead_reckoning import DeadReckoning

    FAIL_AT = {fail_at}

    class Faulty(DeadReckoning):
        def reset(self, initial):
            super().reset(initial)
            self.n = 0

        def predict(self, control, dt):
            super().predict(control, dt)
            self.n += 1

        def estimate(self):
            mean, cov = super().estimate()
            if self.n >= FAIL_AT:
                mean, cov = self.spoil(mean, cov)
            return mean, cov

        def spoil(self, mean, cov):
            return mean, cov

    class RaisesInPredict(Faulty):
        def predict(self, control, dt):
            super().predict(control, dt)
            if self.n >= FAIL_AT:
                raise ValueError("student bug in predict")

    class RaisesInUpdate(Faulty):
        def update(self, measurements):
            if self.n >= FAIL_AT:
                {}["missing"]

    class RaisesInEstimate(Faulty):
        def spoil(self, mean, cov):
            raise np.linalg.LinAlgError("Singular matrix")

    class NanMean(Faulty):
        def spoil(self, mean, cov):
            mean[0] = np.nan
            return mean, cov

    class InfCov(Faulty):
        def spoil(self, mean, cov):
            cov[1, 1] = np.inf
            return mean, cov

    class WrongMeanShape(Faulty):
        def spoil(self, mean, cov):
            return mean[:2], cov

    class ColumnMean(Faulty):
        def spoil(self, mean, cov):
            return mean.reshape(3, 1), cov

    class WrongCovShape(Faulty):
        def spoil(self, mean, cov):
            return mean, cov[:2, :2]

    class NotSymmetric(Faulty):
        def spoil(self, mean, cov):
            cov[0, 1] += 0.5
            return mean, cov

    class NotPSD(Faulty):
        def spoil(self, mean, cov):
            return mean, np.diag([0.1, -0.2, 0.1])

    class ReturnsNone(Faulty):
        def spoil(self, mean, cov):
            return None

    class Slow(Faulty):
        def spoil(self, mean, cov):
            return mean, cov

        def update(self, measurements):
            time.sleep(0.06)
""").replace("{fail_at}", str(FAIL_AT))

KINDS = {
    "RaisesInPredict": "ValueError: student bug in predict",
    "RaisesInUpdate": "KeyError",
    "RaisesInEstimate": "LinAlgError: Singular matrix",
    "NanMean": "NaN or infinity",
    "InfCov": "NaN or infinity",
    "WrongMeanShape": "shapes (2,)",
    "ColumnMean": "shapes (3, 1)",
    "WrongCovShape": "(2, 2)",
    "NotSymmetric": "not symmetric",
    "NotPSD": "not positive semi-definite",
    "ReturnsNone": "TypeError",
}
STEPS = 40


@pytest.fixture(scope="module")
def faulty_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("faulty") / "faulty.py"
    path.write_text(FAULTY)
    return path


@pytest.fixture(scope="module")
def scenario():
    return load_scenario("default")


@pytest.fixture(scope="module")
def reference(scenario):
    """Dead reckoning alone: what the healthy filter must still produce beside a faulty one."""
    runner = FilterRunner({"dead_reckoning": build_filter("dead_reckoning", scenario, 3)})
    sim = Simulation(scenario, 3)
    steps = [sim.step() for _ in range(STEPS)]
    for s in steps:
        runner.feed(s)
    return steps, runner.tracks["dead_reckoning"]


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_each_faulty_kind_is_switched_off_and_the_others_go_on(kind, faulty_file, scenario,
                                                               reference):
    steps, ref = reference
    bad = build_filter(f"{faulty_file}:{kind}", scenario, 3, name="bad")
    dr = build_filter("dead_reckoning", scenario, 3)
    runner = FilterRunner({"bad": bad, "dead_reckoning": dr})
    for s in steps:
        runner.feed(s)
    track = runner.tracks["bad"]
    assert track.failed is not None and KINDS[kind] in track.failed
    assert "\n" not in track.failed
    assert len(track.means) == FAIL_AT - 1          # history up to the fault is kept
    if kind.startswith("Raises") or kind == "ReturnsNone":
        assert "Traceback" in track.traceback
    assert isolation.status_line(track).startswith("bad switched off: ")
    good = runner.tracks["dead_reckoning"]
    assert good.failed is None and len(good.means) == STEPS
    np.testing.assert_array_equal(np.array(good.means), np.array(ref.means))
    np.testing.assert_array_equal(np.array(good.covs), np.array(ref.covs))


def test_a_switched_off_filter_is_not_called_again(faulty_file, scenario, reference):
    steps, _ = reference
    bad = build_filter(f"{faulty_file}:RaisesInPredict", scenario, 3)
    runner = FilterRunner({"bad": bad})
    for s in steps:
        runner.feed(s)
    assert bad.n == FAIL_AT


def test_run_command_marks_the_filter_failed_and_keeps_the_others(faulty_file, capsys):
    code = main(["run", "default", "--filter", f"{faulty_file}:RaisesInUpdate",
                 "--filter", f"{faulty_file}:NotPSD", "--filter", "dead_reckoning",
                 "--duration", "2", "--json"])
    out, err = capsys.readouterr()
    assert code == 0
    data = json.loads(out)
    f = data["filters"]
    assert "KeyError" in f["RaisesInUpdate"]["failed"]
    assert "positive semi-definite" in f["NotPSD"]["failed"]
    assert "failed" not in f["dead_reckoning"] and np.isfinite(f["dead_reckoning"]["pos_rmse_m"])
    assert data["steps"] == 40
    assert "Traceback" in err and "student bug" not in err and "RaisesInUpdate" in err


def test_headless_results_of_the_others_do_not_change(faulty_file, scenario):
    alone = run_headless(scenario, ["dead_reckoning"], seed=4, duration=2.0).filter_summary()
    mixed = run_headless(scenario, [f"{faulty_file}:NanMean", "dead_reckoning"], seed=4,
                         duration=2.0).filter_summary()
    assert "NaN" in mixed["NanMean"]["failed"]
    for key in ("pos_rmse_m", "heading_rmse_rad", "anees"):
        assert mixed["dead_reckoning"][key] == alone["dead_reckoning"][key]


def test_slow_filter_gets_a_warning_and_keeps_running(faulty_file, scenario, reference):
    steps, _ = reference
    slow = build_filter(f"{faulty_file}:Slow", scenario, 3)
    dr = build_filter("dead_reckoning", scenario, 3)
    runner = FilterRunner({"slow": slow, "dead_reckoning": dr})
    for s in steps[: isolation.SLOW_MIN_STEPS]:
        runner.feed(s)
    track = runner.tracks["slow"]
    assert track.failed is None and len(track.means) == isolation.SLOW_MIN_STEPS
    assert track.slow_warning and "ms per step" in track.slow_warning
    assert "slow" in isolation.status_line(track)
    assert runner.tracks["dead_reckoning"].slow_warning is None


def _track():
    return FilterTrack("t", object())


def test_one_slow_step_among_fast_ones_does_not_warn():
    tr = _track()
    for ns in [200_000_000] + [20_000] * 20:      # a 200 ms first step, then 20 us steps
        isolation.note_step_time(tr, ns)
    assert tr.slow_warning is None


def test_two_spikes_in_the_window_do_warn():
    """Leaving out one step is not a loophole: a filter slow half the time is reported."""
    tr = _track()
    for ns in [120_000_000, 20_000]:
        isolation.note_step_time(tr, ns)
    assert tr.slow_warning is None                 # too few steps
    isolation.note_step_time(tr, 120_000_000)      # (120 + 120 + 0.02 - 120) / 2 = 60 ms
    assert "60 ms" in tr.slow_warning


def test_warning_needs_the_recent_mean_over_50_ms():
    tr = _track()
    for _ in range(isolation.SLOW_WINDOW):
        isolation.note_step_time(tr, 49_000_000)
    assert tr.slow_warning is None                 # 49 ms: under the limit
    tr = _track()
    for _ in range(isolation.SLOW_MIN_STEPS - 1):
        isolation.note_step_time(tr, 80_000_000)
    assert tr.slow_warning is None                 # too few steps to judge
    isolation.note_step_time(tr, 80_000_000)
    assert "80 ms" in tr.slow_warning


def test_status_line_is_none_for_a_healthy_filter():
    assert isolation.status_line(_track()) is None


def test_real_sleep_is_measured(faulty_file, scenario):
    """The warning comes from the runner's own clock, not a number the filter reports."""
    slow = build_filter(f"{faulty_file}:Slow", scenario, 3)
    runner = FilterRunner({"slow": slow})
    sim = Simulation(scenario, 3)
    t0 = time.perf_counter()
    for _ in range(3):
        runner.feed(sim.step())
    assert runner.tracks["slow"].us_per_step >= 60_000 * 0.95
    assert time.perf_counter() - t0 >= 0.17


@pytest.mark.parametrize("kind", ["RaisesInUpdate", "NanMean", "NotPSD"])
def test_the_window_keeps_stepping_past_a_faulty_filter(kind, faulty_file, scenario):
    """Under the dummy SDL driver: the faulty filter is switched off, its status carries the
    message for the HUD, and the simulation and dead reckoning go on tick after tick."""
    import beacon_sim.app.main as app_main
    from beacon_sim.runs.live import Session

    session = Session(scenario, [f"{faulty_file}:{kind}", "dead_reckoning"], seed=3)
    app = app_main.App(session, (640, 400), scripted=True)
    try:
        app.run(40)
        bad, good = session.runner.tracks[kind], session.runner.tracks["dead_reckoning"]
        assert bad.failed and KINDS[kind] in bad.failed
        assert session.status[kind].failed == bad.failed
        ticks = session.sim.tick
        assert ticks > FAIL_AT + 5 and good.failed is None and len(good.means) == ticks
        app.run(app.frames + 20)
        assert session.sim.tick > ticks and len(good.means) == session.sim.tick
    finally:
        app.close()
