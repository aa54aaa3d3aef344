"""The live bound in a map world: the window's LiveBound takes the range finder's
scans (it used to switch itself off), equals the offline PCRB tick by tick, and is drawn:
in the magnifier's inner box when it is millimetres beside a filter's centimetres."""

from __future__ import annotations

import numpy as np

from beacon_sim.app.window import SCRIPTED_FRAME_S, App
from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.evaluation.live_bound import LiveBound
from beacon_sim.evaluation.pcrb import pcrb
from beacon_sim.runs.live import Session


def test_the_live_bound_of_a_map_world_equals_the_offline_pcrb():
    for name in ("office", "corridor"):
        sc = load_scenario(name)
        steps = Simulation(sc, sc.seed).run(6.0)
        lb = LiveBound(sc)
        live = []
        for st in steps:
            lb.feed(st)
            live.append(lb.P.copy())
        assert lb.valid
        truths = np.array([sc.initial_pose] + [st.true_pose for st in steps])[None]
        ctrl = np.array([[st.control.v, st.control.omega] for st in steps])[None]
        np.testing.assert_allclose(np.array(live), pcrb(sc, truths, ctrl)[0], rtol=1e-12,
                                   atol=1e-15)
        pos, head = lb.sigmas()
        assert 0.0 < pos < 0.05 and 0.0 < head < 0.05, (name, pos, head)


def test_the_window_draws_the_map_worlds_bound_in_the_magnifier():
    sc = load_scenario("office")
    s = Session(sc, ["mcl"], None)
    s.toggle_autopilot()
    app = App(s, (1100, 640), scripted=True)
    try:
        while s.time < 8.0:
            app.frame(SCRIPTED_FRAME_S)
        app.act("pause")
        assert app.bound is not None and app.bound.valid
        app.draw()
        mag = app.renderer.last_magnifier
        assert mag is None or mag["bound_px"] is None          # B is off: no bound drawn
        app.act("bound")
        app.draw()
        mag = app.renderer.last_magnifier
        assert mag is not None and mag["bound_px"] is not None
        if mag["bound_px"] < 30.0:                              # too small: the inner box
            assert mag["bound_zoom"] is not None and mag["bound_zoom"] > 1.0
            assert mag["bound_px"] * mag["bound_zoom"] > 30.0
    finally:
        app.close()
