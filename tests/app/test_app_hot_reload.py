"""Hot reload inside the window: the App watches every ``file.py:Class`` filter and polls
it from its own loop (under SDL's dummy driver, scripted frames of 1/60 s)."""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import numpy as np
import pytest
from hot_reload_helpers import SOURCE, write

from beacon_sim.app.window import App
from beacon_sim.cli.main import build_parser
from beacon_sim.core.scenario import load_scenario
from beacon_sim.runs.live import Session


@pytest.fixture
def window(tmp_path):
    path = tmp_path / "tmp_shift.py"
    write(path, SOURCE.format(offset=0.0), bump_s=0)
    args = build_parser().parse_args(["play", "--filter", f"{path}:Shift",
                                      "--filter", "dead_reckoning", "--no-record"])
    sc = load_scenario(args.scenario)
    app = App(Session(sc, args.filters, None), (900, 560), scripted=True)
    yield app, path, sc
    app.close()


def x_offset(app, sc) -> float:
    track = app.session.runner.tracks["Shift"]
    return float(track.means[-1][0] - sc.initial_belief.mean[0])


def test_saving_the_file_swaps_the_new_version_in_and_a_syntax_error_keeps_the_old(
        window, capsys, tmp_path):
    app, path, sc = window
    assert list(app.watchers) == ["Shift"]          # dead_reckoning is not a file: not watched
    app.run(app.frames + 30)
    assert x_offset(app, sc) == 0.0
    first = app.session.runner.tracks["Shift"].filter

    write(path, SOURCE.format(offset=2.5), bump_s=1)
    app.run(app.frames + 20)                         # under the 1 s poll interval: not yet
    assert app.session.runner.tracks["Shift"].filter is first
    app.run(app.frames + 60)                         # past it (60 frames = 1 s)
    track = app.session.runner.tracks["Shift"]
    assert track.filter is not first and track.name == "Shift"
    assert x_offset(app, sc) == pytest.approx(2.5)   # the new constant is what runs
    assert "reloaded" in app.banner_text and "initial belief" in app.banner_text
    assert app.now < app.banner_until                # still on screen
    second = track.filter
    ticks_before = len(track.means)

    write(path, "OFFSET = = 1\n", bump_s=2)
    app.run(app.frames + 70)
    track = app.session.runner.tracks["Shift"]
    assert track.filter is second and track.failed is None    # the previous version runs on
    assert len(track.means) > ticks_before and x_offset(app, sc) == pytest.approx(2.5)
    assert "not reloaded" in app.banner_text and "SyntaxError" in app.banner_text
    assert "SyntaxError" in app.reload_errors["Shift"]        # also kept in the panel
    err = capsys.readouterr().err
    assert "Traceback" in err and "SyntaxError" in err
    app.save_screenshot(tmp_path / "reload_error.png")
    assert (tmp_path / "reload_error.png").stat().st_size > 10_000

    write(path, SOURCE.format(offset=-1.0), bump_s=3)   # fixed: reloads, error note cleared
    app.run(app.frames + 70)
    assert x_offset(app, sc) == pytest.approx(-1.0) and "Shift" not in app.reload_errors


def test_the_panel_shows_the_status_line_of_a_slow_or_switched_off_filter(window):
    app, _, _ = window
    app.run(app.frames + 5)
    track = app.session.runner.tracks["dead_reckoning"]
    track.slow_warning = "slow: 80 ms per step (over 50 ms; the simulation cannot run in real time)"
    app.session.tick()  # the panel's status follows the runner tick by tick
    drawn: list[str] = []
    blit = app.hud._blit
    app.hud._blit = lambda surf, text, *a, **k: drawn.append(text) or blit(surf, text, *a, **k)
    app.run(app.frames + 1)
    assert any("slow: 80 ms" in t for t in drawn)
    track.failed = "estimate() returned NaN or infinity"
    app.session.tick()
    drawn.clear()
    app.run(app.frames + 1)
    assert any("switched off" in t for t in drawn) and any("NaN" in t for t in drawn)


def test_a_reloaded_filter_catches_up_to_where_a_run_from_the_start_is():
    """Hot reload re-runs the new filter over the session so far (same Steps, same resets):
    its estimates equal, bit for bit, those of a filter that ran from the start."""
    from beacon_sim.core.scenario import load_scenario
    from beacon_sim.hosting.loading import build_filter

    sc = load_scenario("default")
    straight = Session(sc, ["ekf", "dead_reckoning"], seed=4)
    reloaded = Session(sc, ["ekf", "dead_reckoning"], seed=4)
    for s in (straight, reloaded):
        s.toggle_autopilot()
        for k in range(300):
            if k == 120:
                s.command({"kind": "reset"})
            s.tick()
    fresh = build_filter("ekf", sc, 4, name="ekf")
    message = reloaded.replace_filter("ekf", fresh)
    assert "run over the 300 ticks" in message
    a, b = straight.runner.tracks["ekf"], reloaded.runner.tracks["ekf"]
    assert b.filter is fresh and b.ticks == a.ticks
    np.testing.assert_array_equal(np.array(b.means), np.array(a.means))
    np.testing.assert_array_equal(np.array(b.covs), np.array(a.covs))
    assert reloaded.status["ekf"].pos_err == straight.status["ekf"].pos_err
    for s in (straight, reloaded):  # and they go on together
        s.tick()
    np.testing.assert_array_equal(reloaded.runner.tracks["ekf"].means[-1],
                                  straight.runner.tracks["ekf"].means[-1])


def test_a_reload_too_slow_to_catch_up_restarts_from_the_initial_belief():
    from beacon_sim.core.scenario import load_scenario
    from beacon_sim.hosting.loading import build_filter

    sc = load_scenario("default")
    s = Session(sc, ["ekf"], seed=4)
    for _ in range(50):
        s.tick()
    message = s.replace_filter("ekf", build_filter("ekf", sc, 4, name="ekf"), budget_s=0.0)
    assert "from the initial belief" in message
    assert len(s.runner.tracks["ekf"].means) == 0
