"""Foxglove shows what the window shows: particles, the grid belief, the SLAM map with its
ellipses, the PCRB ellipse, readings and covariance as numbers; in an MCAP export and live
(a WebSocket client), each message decoded with the schema its channel carries and checked
against the filters and the bound it came from."""

from __future__ import annotations

import json

import numpy as np
import pytest
from foxglove_client import FoxgloveClient
from mcap_helpers import read, stamp_ns, xy

from beacon_sim.cli.export import FrameKeeper
from beacon_sim.core.scenario import load_scenario
from beacon_sim.evaluation.live_bound import LiveBound
from beacon_sim.evaluation.pcrb import pcrb
from beacon_sim.filters.base import GridBelief, ParticleBelief
from beacon_sim.io.export import filter_arrays, step_arrays
from beacon_sim.io.foxglove import MAX_PARTICLES_SHOWN, shown_particles
from beacon_sim.io.foxglove_live import LiveFoxglove
from beacon_sim.io.mcap import layout_path, write_mcap
from beacon_sim.runs.headless import run_headless
from beacon_sim.runs.live import Session


def grid_values(msg: dict) -> np.ndarray:
    """A decoded foxglove.Grid's FLOAT32 cells as (rows, columns)."""
    import base64
    data = np.frombuffer(base64.b64decode(msg["data"]), dtype="<f4")
    return data.reshape(-1, msg["column_count"])


def particles_of(msg: dict) -> np.ndarray:
    from mcap_helpers import theta
    return np.array([[*xy(p), theta(p["orientation"])] for p in msg["poses"]])


def landmarks_of(msg: dict) -> list[list[float]]:
    """A map entity's metadata: [id, x, y, cov_xx, cov_xy, cov_yy] per landmark."""
    ent = msg["entities"][0]
    return [[float(v) for v in kv["value"].split()] for kv in ent.get("metadata", [])]


def check_particles(msg, stats, bel: ParticleBelief):
    want = shown_particles(bel.poses, bel.weights)
    got = particles_of(msg)
    assert len(got) == min(len(bel.poses), MAX_PARTICLES_SHOWN) == stats["particles_shown"]
    assert stats["particles_total"] == len(bel.poses)
    np.testing.assert_array_equal(got[:, :2], want[:, :2])
    np.testing.assert_allclose(np.cos(got[:, 2] - want[:, 2]), 1.0, atol=1e-12)


def check_grid(msg, bel: GridBelief):
    np.testing.assert_array_equal(grid_values(msg), np.asarray(bel.prob, dtype=np.float32).T)
    assert xy(msg["pose"]) == [float(bel.origin[0]), float(bel.origin[1])]
    assert msg["cell_size"]["x"] == bel.cell and msg["fields"][0]["name"] == "probability"


def check_map(msg, lm):
    rows = landmarks_of(msg)
    ids = list(range(len(lm.means))) if lm.ids is None else list(lm.ids)
    assert [r[0] for r in rows] == ids
    np.testing.assert_array_equal(np.reshape([r[1:3] for r in rows], (-1, 2)), np.reshape(lm.means, (-1, 2)))
    np.testing.assert_array_equal(np.reshape([r[3:6] for r in rows], (-1, 3)),
                                  np.reshape([[c[0, 0], c[0, 1], c[1, 1]] for c in lm.covs], (-1, 3)))
    ent = msg["entities"][0]
    assert len(ent.get("spheres", [])) == 2 * len(ids)  # protobuf JSON leaves out empty lists
    assert [t["text"] for t in ent.get("texts", [])] == [f"L{i}" for i in ids]


def test_mcap_carries_the_beliefs_and_the_bound(tmp_path):
    sc = load_scenario("default")
    keeper = FrameKeeper()
    r = run_headless(sc, ["pf", "histogram", "ekf"], seed=4, duration=3.0, on_tick=keeper)
    a = step_arrays(sc, r.steps)
    a.update(filter_arrays(r.runner.tracks, len(r.steps)))
    out = write_mcap(tmp_path / "run.mcap", sc, a, None, keeper.with_bound(sc, a))
    _, msgs = read(out)
    n = len(r.steps)
    dt_ns = round(sc.dt * 1e9)
    # every tick: the particles and the grid of that tick's frame, message by message
    assert len(msgs["/filters/pf/particles"]) == len(msgs["/filters/histogram/grid"]) == n
    stats = {m["tick"]: m for _, _, m, _ in msgs["/filters/pf/stats"]}
    for (t, _, pm, _), (t2, _, gm, _) in zip(msgs["/filters/pf/particles"], msgs["/filters/histogram/grid"],
                                            strict=True):
        k = t // dt_ns
        assert t == t2 == stamp_ns(pm["timestamp"]) and 1 <= k <= n
        frame = keeper.frames[k]
        shown, total = frame.particles["pf"]
        assert stats[k]["particles_shown"] == len(shown) and stats[k]["particles_total"] == total
        np.testing.assert_array_equal(particles_of(pm)[:, :2], shown[:, :2])
        np.testing.assert_array_equal(grid_values(gm), frame.grids["histogram"].prob.T)
    # the last tick's equal the filters' own beliefs now
    check_particles(msgs["/filters/pf/particles"][-1][2], stats[n], r.runner.tracks["pf"].filter.belief())
    check_grid(msgs["/filters/histogram/grid"][-1][2], r.runner.tracks["histogram"].filter.belief())
    # the PCRB: its covariance and sigmas are the offline bound's, tick by tick
    P = pcrb(sc, a["truth"][None], a["control"][None])[0]
    bound = [m for _, _, m, _ in msgs["/pcrb/stats"]]
    assert [m["tick"] for m in bound] == list(range(1, n + 1))
    for m in bound:
        Pk = P[m["tick"] - 1]
        want = [Pk[0, 0], Pk[0, 1], Pk[1, 1], Pk[2, 2]]
        assert [m["cov_xx"], m["cov_xy"], m["cov_yy"], m["cov_tt"]] == want
        assert m["sigma_x_m"] == pytest.approx(np.sqrt(Pk[0, 0]), rel=1e-15)
    ell = msgs["/pcrb"][-1][2]["entities"][0]["spheres"][0]
    assert xy(ell["pose"]) == list(a["truth"][-1, :2])
    # the covariance as numbers on the stats topic, the estimates table's
    ekf = [m for _, _, m, _ in msgs["/filters/ekf/stats"]]
    cov = np.asarray(a["est_cov"][2])
    assert [m["cov_xt"] for m in ekf] == list(cov[:, 0, 2])
    assert [m["cov_tt"] for m in ekf] == list(cov[:, 2, 2])
    # the layout beside it opens these topics
    lay = json.loads(layout_path(out).read_text())
    shown3d = lay["configById"]["3D!beacon"]["topics"]
    assert {"/filters/pf/particles", "/filters/histogram/grid", "/pcrb", "/world"} <= set(shown3d)
    assert set(shown3d) <= set(msgs)
    paths = [p["value"].split(".")[0] for c in lay["configById"].values() for p in c.get("paths", [])]
    assert set(paths) <= set(msgs) and "/pcrb/stats" in paths


def test_mcap_carries_the_slam_maps(tmp_path):
    sc = load_scenario("slam_loop")
    keeper = FrameKeeper()
    r = run_headless(sc, None, seed=2, duration=4.0, on_tick=keeper)
    a = step_arrays(sc, r.steps)
    a.update(filter_arrays(r.runner.tracks, len(r.steps)))
    out = write_mcap(tmp_path / "slam.mcap", sc, a, None, keeper.with_bound(sc, a))
    _, msgs = read(out)
    for name in ("ekf_slam", "fastslam"):
        rows = msgs[f"/filters/{name}/map"]
        assert len(rows) == len(r.steps)
        for t, _, m, _ in rows:
            check_map(m, keeper.frames[t // round(sc.dt * 1e9)].landmarks[name])
        final = r.runner.tracks[name].filter.landmarks()
        assert len(final.means) > 0
        check_map(rows[-1][2], final)
    assert "/filters/fastslam/particles" in msgs  # FastSLAM's pose particles


@pytest.fixture
def no_step_limit(monkeypatch):
    """A decoding test, not a time-limit test: a loaded machine must not switch a filter off."""
    from beacon_sim.runs import live

    monkeypatch.setattr(live, "WINDOW_STEP_LIMIT_S", 60.0)


def run_live(scenario: str, filters: list[str], ticks: int, topics: set[str]):
    sc = load_scenario(scenario)
    session = Session(sc, filters, 3)
    live = LiveFoxglove(sc, session.names, port=0, bound=LiveBound(sc)).attach(session)
    try:
        client = FoxgloveClient(live.port)
        client.pump(10, until=lambda c: topics <= {ch["topic"] for ch in c.channels.values()}
                    and len(c.subs) >= len(c.channels))
        advertised = {ch["topic"]: ch["schemaName"] for ch in client.channels.values()}
        for _ in range(ticks):
            session.tick()
            client.pump(0.02)
        end = ticks * round(sc.dt * 1e9)
        client.pump(30, until=lambda c: all(any(t == end for t, _ in c.messages.get(tp, []))
                                            for tp in topics))
    finally:
        live.close()
    client.close()
    return session, live, client.messages, advertised


def test_a_live_client_decodes_particles_grid_bound_and_readings(no_step_limit):
    topics = {"/filters/pf/particles", "/filters/histogram/grid", "/pcrb", "/pcrb/stats", "/filters/pf/stats"}
    session, live, got, advertised = run_live("default", ["pf", "histogram"], 30, topics)
    assert advertised["/filters/pf/particles"] == "foxglove.PosesInFrame"
    assert advertised["/filters/histogram/grid"] == "foxglove.Grid"
    assert advertised["/pcrb"] == "foxglove.SceneUpdate"
    assert advertised["/pcrb/stats"] == "beacon_sim.BoundStats"
    assert advertised["/readings/values"] == "beacon_sim.Readings"
    last_stats = next(m for _, m in got["/filters/pf/stats"] if m["tick"] == 30)
    check_particles(got["/filters/pf/particles"][-1][1], last_stats, session.belief("pf"))
    check_grid(got["/filters/histogram/grid"][-1][1], session.belief("histogram"))
    b = got["/pcrb/stats"][-1][1]
    assert b["tick"] == 30 and [b["cov_xx"], b["cov_yy"]] == [live.bound.P[0, 0], live.bound.P[1, 1]]
    assert got["/readings/values"] and all(r["kind"] == "range_bearing" for _, m in got["/readings/values"]
                                           for r in m["readings"])


def test_a_live_client_decodes_the_slam_map(no_step_limit):
    topics = {"/filters/ekf_slam/map", "/filters/fastslam/map"}
    session, _, got, advertised = run_live("slam_loop", ["ekf_slam", "fastslam"], 20, topics)
    assert advertised["/filters/ekf_slam/map"] == "foxglove.SceneUpdate"
    for name in ("ekf_slam", "fastslam"):
        check_map(got[f"/filters/{name}/map"][-1][1], session.runner.tracks[name].filter.landmarks())
