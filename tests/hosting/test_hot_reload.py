"""Hot reload: a filter file changed on disk is rebuilt; a broken one is reported and the
previous version keeps running (driven through FilterFileWatcher directly)."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest
from hot_reload_helpers import SOURCE, write

from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.hosting.hot_reload import FilterFileWatcher, replace_in_runner, source_of
from beacon_sim.hosting.loading import build_filter
from beacon_sim.hosting.runner import FilterRunner


class FakeClock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


@pytest.fixture
def scenario():
    return load_scenario("default")


@pytest.fixture
def setup(tmp_path, scenario):
    path = tmp_path / "shift.py"
    path.write_text(SOURCE.format(offset=1.0))
    spec = f"{path}:Shift"
    clock = FakeClock()
    watcher = FilterFileWatcher(spec, scenario, seed=5, name="mine", clock=clock)
    flt = build_filter(spec, scenario, 5, name="mine")
    return path, spec, clock, watcher, flt


def x_offset(flt, scenario):
    return flt.estimate()[0][0] - scenario.initial_belief.mean[0]


def test_unchanged_file_gives_nothing(setup):
    path, _, clock, watcher, _ = setup
    assert watcher.watchable and watcher.path == path
    for _ in range(3):
        clock.t += 2.0
        res = watcher.poll()
        assert not res.changed and res.new_filter is None and res.error is None


def test_changed_file_is_rebuilt_from_the_initial_belief(setup, scenario):
    path, _, clock, watcher, flt = setup
    assert x_offset(flt, scenario) == pytest.approx(1.0)
    write(path, SOURCE.format(offset=2.5), bump_s=1)
    clock.t += 1.5
    res = watcher.poll()
    assert res.error is None and res.new_filter is not None
    assert x_offset(res.new_filter, scenario) == pytest.approx(2.5)
    assert res.new_filter.steps == 0          # reset, not carried over
    assert "reloaded" in res.message and watcher.reloads == 1
    clock.t += 1.5
    assert not watcher.poll().changed         # reported once


def test_poll_looks_at_most_once_per_interval(setup, scenario):
    path, _, clock, watcher, _ = setup
    write(path, SOURCE.format(offset=3.0), bump_s=1)
    clock.t += 0.5
    assert not watcher.poll().changed         # too early
    clock.t += 0.6
    res = watcher.poll()
    assert x_offset(res.new_filter, scenario) == pytest.approx(3.0)


def test_syntax_error_is_reported_and_the_next_fix_loads(setup, scenario):
    path, _, clock, watcher, _ = setup
    write(path, SOURCE.format(offset=1.0) + "\ndef broken(:\n", bump_s=1)
    clock.t += 2
    res = watcher.poll()
    assert res.new_filter is None
    assert "SyntaxError" in res.error and "previous version keeps running" in res.error
    assert "\n" not in res.error and res.traceback
    write(path, SOURCE.format(offset=4.0), bump_s=2)
    clock.t += 2
    res = watcher.poll()
    assert res.error is None and x_offset(res.new_filter, scenario) == pytest.approx(4.0)


def test_import_and_construction_errors_are_reported(setup):
    path, _, clock, watcher, _ = setup
    write(path, "import no_such_module_for_beacon_sim\n" + SOURCE.format(offset=1.0), bump_s=1)
    clock.t += 2
    res = watcher.poll()
    assert res.new_filter is None and "no_such_module_for_beacon_sim" in res.error
    broken_init = SOURCE.format(offset=1.0) + textwrap.dedent("""
        def _init(self, ctx):
            raise ZeroDivisionError("boom in __init__")
        Shift.__init__ = _init
    """)
    write(path, broken_init, bump_s=2)
    clock.t += 2
    res = watcher.poll()
    assert res.new_filter is None and "ZeroDivisionError: boom in __init__" in res.error
    write(path, SOURCE.format(offset=1.0).replace("class Shift", "class Renamed"), bump_s=3)
    clock.t += 2
    res = watcher.poll()
    assert res.new_filter is None and "Shift" in res.error


def test_deleted_file_keeps_previous_version(setup):
    path, _, clock, watcher, _ = setup
    path.unlink()
    clock.t += 2
    res = watcher.poll()
    assert res.new_filter is None and "gone" in res.error


def test_reloaded_filter_replaces_its_track_and_the_run_goes_on(setup, scenario):
    path, _, clock, watcher, flt = setup
    dr = build_filter("dead_reckoning", scenario, 5)
    runner = FilterRunner({"mine": flt, "dead_reckoning": dr})
    sim = Simulation(scenario, 5)
    for _ in range(20):
        runner.feed(sim.step())
    write(path, SOURCE.format(offset=-1.0), bump_s=1)
    clock.t += 2
    res = watcher.poll()
    replace_in_runner(runner, "mine", res.new_filter)
    for _ in range(10):
        runner.feed(sim.step())
    mine = runner.tracks["mine"]
    assert len(mine.means) == 10 and mine.failed is None
    assert mine.means[-1][0] - scenario.initial_belief.mean[0] == pytest.approx(-1.0)
    assert len(runner.tracks["dead_reckoning"].means) == 30
    assert list(runner.tracks) == ["mine", "dead_reckoning"]


def test_module_specs_are_watched_and_reloaded(tmp_path, monkeypatch, scenario):
    pkg = tmp_path / "hotpkg_beacon"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    mod = pkg / "shiftmod.py"
    mod.write_text(SOURCE.format(offset=1.0))
    monkeypatch.syspath_prepend(str(tmp_path))
    spec = "hotpkg_beacon.shiftmod:Shift"
    try:
        path, module = source_of(spec)
        assert path.resolve() == mod.resolve() and module == "hotpkg_beacon.shiftmod"
        clock = FakeClock()
        watcher = FilterFileWatcher(spec, scenario, seed=1, clock=clock)
        assert x_offset(build_filter(spec, scenario, 1), scenario) == pytest.approx(1.0)
        write(mod, SOURCE.format(offset=7.0), bump_s=1)
        clock.t += 2
        res = watcher.poll()
        assert res.error is None, res.traceback
        assert x_offset(res.new_filter, scenario) == pytest.approx(7.0)
    finally:
        import sys
        for name in ("hotpkg_beacon.shiftmod", "hotpkg_beacon"):
            sys.modules.pop(name, None)


def test_builtin_names_point_at_their_module_file():
    path, module = source_of("dead_reckoning")
    assert module == "beacon_sim.filters.gaussian.dead_reckoning" and path.name == "dead_reckoning.py"
    assert source_of("no_such_filter_name") == (None, None)


def test_reload_restarts_the_filter_random_stream(tmp_path, scenario):
    """Rebuilt filters draw the same numbers as a fresh build: the reload is reproducible."""
    path = tmp_path / "noisy.py"
    path.write_text(SOURCE.format(offset=0.0))
    spec = f"{path}:Shift"
    first = build_filter(spec, scenario, 9, name="n").ctx.rng.random(4)
    watcher = FilterFileWatcher(spec, scenario, seed=9, name="n", interval=0.0)
    write(path, SOURCE.format(offset=0.5), bump_s=1)
    res = watcher.poll()
    np.testing.assert_array_equal(res.new_filter.ctx.rng.random(4), first)


def test_reload_inside_the_window_under_the_dummy_driver(setup, scenario):
    """The window's own hooks (App.swap_filter, App.flash) with the watcher, as the loop
    will call them: the new version runs in the window, a broken one leaves the old one."""
    import beacon_sim.app.main as app_main
    from beacon_sim.runs.live import Session

    path, spec, clock, watcher, _ = setup
    session = Session(scenario, [spec, "dead_reckoning"], seed=5)
    app = app_main.App(session, (640, 400), scripted=True)
    try:
        name = session.names[0]
        watcher.name = name
        app.run(app.frames + 10)              # run() counts frames from the start
        write(path, SOURCE.format(offset=2.0), bump_s=1)
        clock.t += 2
        res = watcher.poll()
        app.swap_filter(name, res.new_filter)
        app.flash(res.message)
        app.run(app.frames + 10)
        track = session.runner.tracks[name]
        assert track.filter is res.new_filter and track.means and track.failed is None
        assert track.means[-1][0] - scenario.initial_belief.mean[0] == pytest.approx(2.0)
        assert "reloaded" in app.banner_text
        write(path, "this is not python\n", bump_s=2)
        clock.t += 2
        bad = watcher.poll()
        assert bad.new_filter is None
        app.flash(bad.error)
        app.run(app.frames + 10)
        assert session.runner.tracks[name].filter is res.new_filter    # previous version runs on
        assert session.runner.tracks[name].failed is None
        assert "not reloaded" in app.banner_text
        # the reloaded filter caught up over the session: as many estimates as one that ran throughout
        assert len(session.runner.tracks[name].means) == len(session.runner.tracks["dead_reckoning"].means)
    finally:
        app.close()
