"""The window's time limit on a filter counts the CPU time of the filter's own work, not
wall time: a step that waits (for a core on a loaded machine, or in ``time.sleep``) is
not switched off, one that burns CPU is; a switched-off filter is said on the world and R
brings it back."""

from __future__ import annotations

import textwrap
import time

import pytest

pygame = pytest.importorskip("pygame")

import beacon_sim.runs.live as live  # noqa: E402
from beacon_sim.app.window import App  # noqa: E402
from beacon_sim.core.scenario import load_scenario  # noqa: E402
from beacon_sim.runs.live import Session  # noqa: E402

LIMIT_S = 0.3  # the window's limit in these tests [s of CPU]

SLOW = textwrap.dedent('''
    import time
    from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter

    class Waits(ExtendedKalmanFilter):
        """On tick 3 its predict waits WAIT_S of wall time, using no CPU (as a step does
        that waits for a core on a busy machine)."""
        WAIT_S = 0.0
        def reset(self, initial):
            super().reset(initial)
            self.k = 0
        def predict(self, control, dt):
            super().predict(control, dt)
            self.k += 1
            if self.k == 3:
                self.work()
        def work(self):
            time.sleep(self.WAIT_S)

    class Sleeps(Waits):
        WAIT_S = 3 * LIMIT

    class Burns(Waits):
        """On tick 3 it burns 3 times the limit of its thread's CPU time."""
        def work(self):
            t0 = time.thread_time()
            while time.thread_time() - t0 < 3 * LIMIT:
                pass
''').replace("LIMIT", repr(LIMIT_S))


@pytest.fixture()
def slow_file(tmp_path, monkeypatch):
    monkeypatch.setattr(live, "WINDOW_STEP_LIMIT_S", LIMIT_S)
    path = tmp_path / "slow.py"
    path.write_text(SLOW)
    return path


def test_a_step_that_waits_is_not_switched_off_one_that_burns_cpu_is(slow_file, busy_machine):
    s = Session(load_scenario("default"), [f"{slow_file}:Sleeps", f"{slow_file}:Burns", "ekf"])
    t0 = time.perf_counter()
    for _ in range(6):
        s.tick()
    assert time.perf_counter() - t0 >= 3 * LIMIT_S  # the sleep did cost wall time
    assert s.status["Sleeps"].failed is None
    assert len(s.runner.tracks["Sleeps"].means) == 6
    assert s.status["Burns"].failed == f"time limit: a step took over {LIMIT_S:g} s of CPU"
    assert s.status["ekf"].failed is None


def test_a_switched_off_filter_is_said_on_the_world_and_r_brings_it_back(slow_file):
    app = App(Session(load_scenario("default"), [f"{slow_file}:Burns", "ekf"]), (1024, 768),
              scripted=True)
    try:
        app.run(20)
        s = app.session
        assert "time limit" in s.status["Burns"].failed
        app.draw()
        box = app.hud.off_box
        assert pygame.Rect(app.view.area).contains(box)  # on the world, not in the panel
        lines = app.switched_off_lines()
        assert len(lines) == 1 and lines[0][0].startswith("Burns switched off: time limit")
        assert "R: back on" in lines[0][0] and lines[0][1] == app.colours["Burns"]
        # the box is drawn in the warning colour where the world was
        assert app.screen.get_at(box.topleft)[:3] == (213, 94, 0)
        app.act("reset")
        app.run(app.frames + 1)
        assert s.status["Burns"].failed is None
        assert app.switched_off_lines() == []
        ticks = s.tick_count
        while s.tick_count == ticks:  # one more tick (before its third, which burns again)
            app.run(app.frames + 1)
        assert s.runner.tracks["Burns"].ticks[-1] == s.tick_count  # running again
    finally:
        app.close()


def test_a_filter_that_could_not_be_built_stays_off_after_r(tmp_path):
    path = tmp_path / "broken.py"
    path.write_text("class Broken:\n    def __init__(self, ctx):\n        raise ValueError('no')\n")
    s = Session(load_scenario("default"), [f"{path}:Broken", "ekf"])
    s.tick()
    s.command({"kind": "reset"})
    s.tick()
    assert "construction failed" in s.status["Broken"].failed
    assert s.status["ekf"].failed is None
