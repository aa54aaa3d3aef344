"""The window's filters on a worker thread (runs/filter_worker.py) give the run a synchronous
session gives, bit for bit: the same estimates on every tick, the same figures, the same
recording, byte for byte; user commands land on the same ticks; a filter that raises, loops
or returns garbage is switched off with the same reason at the same time; the worker stops
cleanly."""

from __future__ import annotations

import datetime
import textwrap
import threading
import types

import numpy as np
import pytest

from beacon_sim.core.scenario import load_any_scenario, load_scenario
from beacon_sim.runs import filter_snapshot, live
from beacon_sim.runs import recorder as recorder_mod
from beacon_sim.runs.filter_worker import FilterWorker
from beacon_sim.runs.live import Session
from beacon_sim.runs.recorder import Recorder

BAD = textwrap.dedent('''
    import numpy as np
    from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter

    class Later(ExtendedKalmanFilter):
        """Good for FROM predicts, then ``bad()``."""
        FROM = 25
        def reset(self, initial):
            super().reset(initial)
            self.k = 0
        def predict(self, control, dt):
            super().predict(control, dt)
            self.k += 1
            if self.k >= self.FROM:
                self.bad()
        def bad(self):
            pass

    class Raises(Later):
        def bad(self): raise RuntimeError("broken predict")

    class Loops(Later):
        FROM = 40
        def bad(self):
            while True:
                pass

    class Garbage(Later):
        FROM = 10
        def estimate(self):
            m, c = super().estimate()
            return (m * np.nan, c) if self.k >= self.FROM else (m, c)

    class BeliefRaises(Later):
        FROM = 15
        def belief(self):
            if self.k >= self.FROM:
                raise ValueError("no belief")
            return super().belief()

    class ResetRaises(ExtendedKalmanFilter):
        def reset(self, initial):
            if getattr(self, "started", False):
                raise RuntimeError("no second reset")
            self.started = True
            super().reset(initial)
''')


class _FixedClock:
    """``datetime.datetime`` whose ``now()`` is one fixed instant (the header's "created")."""

    @staticmethod
    def now(tz=None):
        return datetime.datetime(2026, 1, 2, 3, 4, 5, tzinfo=datetime.UTC)


@pytest.fixture
def fixed_created(monkeypatch):
    monkeypatch.setattr(recorder_mod, "_dt", types.SimpleNamespace(datetime=_FixedClock))


def drive(session: Session, ticks: int, threaded: bool, collect_every: int = 3) -> None:
    """A session driven by hand then by its autopilot, with a kidnap, a reset, a global
    reset and a hidden filter on fixed ticks; threaded: the ticks shown every few ticks, as
    frames do."""
    if threaded:
        session.start_worker()
    for k in ("w", "w", "a"):
        session.drive(k)
    for t in range(1, ticks + 1):
        if t == 30:
            session.drive("d")
        if t == 45 and session.has_autopilot:
            session.toggle_autopilot()
        if t == 60:
            session.command({"kind": "kidnap", "pose": [3.0, 2.0, 1.0]})
        if t == 75:
            session.command({"kind": "kidnap"})
        if t == 90:
            session.command({"kind": "reset"})
        if t == 100:
            session.command({"kind": "global_reset"})
        if t == 110:
            session.command({"kind": "toggle", "filter": session.names[0]})
        session.tick()
        if threaded and t % collect_every == 0:
            session.collect()
    if threaded:
        assert session.stop_worker()


def assert_same_run(a: Session, b: Session) -> None:
    """The same truth, the same estimates of every tick, the same figures and trails."""
    assert a.sim.truth_checksum == b.sim.truth_checksum
    assert a.tick_count == b.tick_count and a.names == b.names
    for name in a.names:
        for ra, rb in zip(a.filters_run.members, b.filters_run.members, strict=True):
            ta, tb = ra.tracks[name], rb.tracks[name]
            assert list(ta.ticks) == list(tb.ticks), name
            assert ta.failed == tb.failed and ta.failed_time_s == tb.failed_time_s, name
            for x, y in zip(ta.means, tb.means, strict=True):
                assert np.array_equal(x, y), name
            for x, y in zip(ta.covs, tb.covs, strict=True):
                assert np.array_equal(x, y), name
        for sa, sb in zip(a.robot_status[name], b.robot_status[name], strict=True):
            assert (sa.failed, sa.warning) == (sb.failed, sb.warning), name
            assert np.array_equal([sa.pos_err, sa.nees, sa.nees_mean], [sb.pos_err, sb.nees, sb.nees_mean],
                                  equal_nan=True), name
        for ta, tb in zip(a.trails[name], b.trails[name], strict=True):
            assert ta.n == tb.n and np.array_equal(ta.points, tb.points, equal_nan=True), name
    for ta, tb in zip(a.truth_trails, b.truth_trails, strict=True):
        assert ta.n == tb.n and np.array_equal(ta.points, tb.points, equal_nan=True)
    assert a.visible == b.visible


def test_a_threaded_session_records_the_same_file_byte_for_byte(tmp_path, fixed_created):
    sc = load_scenario("default")
    specs = ["ekf", "pf", "histogram"]
    params = {"pf": {"n_particles": 300}}
    sessions, texts = [], []
    for threaded in (False, True):
        path = tmp_path / f"run_{threaded}.jsonl"
        s = Session(sc, specs, 11, params, Recorder(path, sc, 11, specs, params))
        drive(s, 130, threaded)
        s.close()
        sessions.append(s)
        texts.append(path.read_bytes())
    assert_same_run(*sessions)
    assert b'"type": "estimates"' in texts[0] or b'"type":"estimates"' in texts[0]
    assert texts[0] == texts[1]


def test_a_team_threaded_gives_the_synchronous_run(tmp_path, fixed_created):
    team = load_any_scenario("team_sparse")
    specs = list(team.default_filters)
    runs, texts = [], []
    for threaded in (False, True):
        path = tmp_path / f"team_{threaded}.jsonl"
        s = Session(team, specs, 5, {}, Recorder(path, team, 5, specs, {}))
        if threaded:
            s.start_worker()
        for t in range(1, 81):
            if t == 20:
                s.next_robot()
            if t == 40:
                s.command({"kind": "kidnap"})
            if t == 60:
                s.command({"kind": "reset"})
            s.tick()
            if threaded and t % 4 == 0:
                s.collect()
        assert s.stop_worker()
        s.close()
        runs.append(s)
        texts.append(path.read_bytes())
    assert texts[0] == texts[1]
    a, b = runs
    for name in a.names:
        la, lb = a.filters_run.latest(name), b.filters_run.latest(name)
        assert (la is None) == (lb is None)
        if la is not None and lb is not None:
            assert np.array_equal(la[0], lb[0]) and np.array_equal(la[1], lb[1])


def test_failing_filters_are_switched_off_the_same_way_on_the_worker(tmp_path, monkeypatch):
    path = tmp_path / "bad.py"
    path.write_text(BAD)
    for mod in (live, filter_snapshot):
        monkeypatch.setattr(mod, "WINDOW_STEP_LIMIT_S", 0.3)
    kinds = ["Raises", "Loops", "Garbage", "BeliefRaises", "ResetRaises"]
    specs = [f"{path}:{k}" for k in kinds] + ["ekf"]
    runs = []
    for threaded in (False, True):
        s = Session(load_scenario("default"), specs, 4)
        if threaded:
            s.start_worker()
        for t in range(1, 101):
            if t == 20:  # BeliefRaises back on; ResetRaises off
                s.command({"kind": "reset"})
            s.tick()
            if not threaded:
                for name in s.names:  # a frame draws every belief, as the worker reads them
                    s.belief(name)
            elif t % 2 == 0:
                s.collect()
        assert s.stop_worker()
        runs.append(s)
    sync, threaded_run = runs
    for k in kinds:
        assert threaded_run.status[k].failed, k
        assert threaded_run.status[k].failed == sync.status[k].failed, k
        if k == "BeliefRaises":  # belief() is read when a frame draws: a tick the window shows
            continue
        tr, ts = threaded_run.runner.tracks[k], sync.runner.tracks[k]
        assert tr.failed_time_s == ts.failed_time_s and list(tr.ticks) == list(ts.ticks), k
    reasons = {k: threaded_run.status[k].failed for k in kinds}
    assert "broken predict" in reasons["Raises"] and "time limit" in reasons["Loops"]
    assert "NaN" in reasons["Garbage"] and "no belief" in reasons["BeliefRaises"]
    assert "no second reset" in reasons["ResetRaises"]
    assert threaded_run.status["ekf"].failed is None
    assert len(threaded_run.runner.tracks["ekf"].ticks) == 100  # the others went on


def test_the_main_thread_never_calls_a_filter_while_the_worker_runs():
    """Everything a window reads (estimates, beliefs, maps, the step view) comes from the
    tick shown, read on the worker: no call into a filter from the main thread."""
    s = Session(load_scenario("default"), ["ekf", "pf"], 2, {"pf": {"n_particles": 200}})
    s.toggle_autopilot()
    s.start_worker()
    callers: set[int] = set()
    for tr in s.runner.tracks.values():
        flt = tr.filter
        for method in ("predict", "update", "estimate", "belief", "reset"):
            real = getattr(flt, method)

            def spy(*args, _real=real, **kw):
                callers.add(threading.get_ident())
                return _real(*args, **kw)
            setattr(flt, method, spy)
    for t in range(60):
        s.tick()
        if t == 30:
            s.command({"kind": "reset"})
        s.collect()
        for name in s.names:  # what a frame reads
            s.belief(name), s.estimate(name), s.predict_update(name), s.filters
        s.clear_trails()
    assert s.stop_worker()
    assert callers and threading.get_ident() not in callers


def test_the_scene_shown_is_one_tick_truth_and_estimates_alike():
    """With ticks the worker has not finished, the session shows its last finished tick:
    the truth, the time and the estimates of that tick, never a mix."""
    s = Session(load_scenario("default"), ["ekf"], 3)
    s.toggle_autopilot()
    s.start_worker()
    gate = threading.Event()
    flt = s.runner.tracks["ekf"].filter
    real = flt.update

    def held(m):
        gate.wait(30)
        return real(m)
    flt.update = held
    steps = [s.tick() for _ in range(3)]
    assert s.filters_behind and s.collect() == 0
    assert s.tick_count == 0 and s.time == 0.0  # nothing finished: the start is shown
    gate.set()
    s.settle()
    assert not s.filters_behind and s.tick_count == 3
    assert np.array_equal(s.true_pose, steps[-1].steps[0].true_pose)
    est = s.estimate("ekf")
    assert est is not None and np.array_equal(est[0], s.runner.tracks["ekf"].means[-1])
    assert s.stop_worker()


def test_the_worker_runs_jobs_in_order_and_raises_a_job_error_in_the_caller():
    w = FilterWorker()
    for k in range(20):
        w.submit(lambda last, k=k: k)
    assert w.wait(30)
    assert w.results() == list(range(20)) and not w.busy

    def boom(last):
        raise RuntimeError("job failed")
    w.submit(boom)
    w.wait(30)
    with pytest.raises(RuntimeError, match="job failed"):
        w.results()
    assert w.stop(30) and not w.alive
    assert w.stop(1)  # idempotent


def test_a_hot_reload_on_a_threaded_session_lands_between_the_same_ticks(tmp_path, fixed_created):
    """A reload waits for the worker's ticks, then swaps the filter between two ticks: the
    new filter catches up over the same history, and the file says the same."""
    from beacon_sim.hosting.loading import build_filter

    sc = load_scenario("default")
    texts, sessions = [], []
    for threaded in (False, True):
        path = tmp_path / f"reload_{threaded}.jsonl"
        s = Session(sc, ["ekf", "ukf"], 6, {}, Recorder(path, sc, 6, ["ekf", "ukf"], {}))
        s.toggle_autopilot()
        if threaded:
            s.start_worker()
        for t in range(1, 61):
            s.tick()
            if t == 40:
                message = s.replace_filter("ekf", build_filter("ekf", sc, 6, name="ekf"))
                assert "run over the 40 ticks" in message
                assert not s.filters_behind and s.tick_count == 40
        s.close()
        texts.append(path.read_bytes())
        sessions.append(s)
    assert b"reloaded live at tick" in texts[0]
    assert texts[0] == texts[1]
    assert_same_run(*sessions)
