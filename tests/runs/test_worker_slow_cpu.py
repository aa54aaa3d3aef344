"""The slow warning ("slow: N ms per step") of filters on the window's worker thread counts
that thread's CPU time: a step that waits (for the interpreter lock while the window draws;
here a sleep) is not slow there, a step that computes is, and without a worker the warning
counts wall time as before."""

from __future__ import annotations

import textwrap

from beacon_sim.core.scenario import load_scenario
from beacon_sim.hosting.runner import SLOW_STEP_MS
from beacon_sim.runs.live import Session

FILTERS = textwrap.dedent(f'''
    import time
    from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter

    class Waits(ExtendedKalmanFilter):
        def predict(self, control, dt):
            super().predict(control, dt)
            time.sleep({2 * SLOW_STEP_MS / 1e3})

    class Computes(ExtendedKalmanFilter):
        def predict(self, control, dt):
            super().predict(control, dt)
            t = time.thread_time()
            while time.thread_time() - t < {2 * SLOW_STEP_MS / 1e3}:
                pass
''')


def warnings(tmp_path, threaded: bool) -> dict[str, str | None]:
    path = tmp_path / "slow.py"
    path.write_text(FILTERS)
    s = Session(load_scenario("default"), [f"{path}:Waits", f"{path}:Computes", "ekf"], 3)
    if threaded:
        s.start_worker()
    try:
        for _ in range(5):
            s.tick()
        s.settle()
    finally:
        assert s.stop_worker()
    return {n: s.runner.tracks[n].slow_warning for n in s.names}


def test_on_the_worker_the_slow_warning_counts_cpu_time(tmp_path):
    got = warnings(tmp_path, threaded=True)
    assert got["Waits"] is None  # slept: no CPU time
    assert got["Computes"] is not None and got["Computes"].startswith("slow: ")
    assert got["ekf"] is None


def test_without_a_worker_the_slow_warning_counts_wall_time(tmp_path):
    got = warnings(tmp_path, threaded=False)
    assert got["Waits"] is not None and got["Computes"] is not None
    assert got["ekf"] is None
