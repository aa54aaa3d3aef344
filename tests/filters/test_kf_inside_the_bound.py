"""The classroom KF's ellipse can be smaller than the best achievable one (the PCRB): its
model (A = I) never turns heading uncertainty into position uncertainty, which the bound's
motion Jacobian does. The panel says so: "kf claims more than is possible"."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

pytest.importorskip("pygame")

from beacon_sim.app.hud import INSIDE_BOUND, inside_the_bound
from beacon_sim.core.scenario import load_scenario
from beacon_sim.evaluation.live_bound import LiveBound
from beacon_sim.runs.live import Session
from beacon_sim.runs.scene import FilterStatus


def test_a_filter_below_the_bound_is_named():
    st = {n: FilterStatus(n) for n in ("kf", "dead_reckoning", "off")}
    st["kf"].pos_sigma, st["dead_reckoning"].pos_sigma, st["off"].pos_sigma = 0.25, 0.6, 0.1
    st["off"].failed = "gone"
    scene = SimpleNamespace(names=list(st), status=st, visible={n: True for n in st})
    assert inside_the_bound(scene, 0.34) == ["kf"]
    assert inside_the_bound(scene, 0.25 / INSIDE_BOUND * 0.999) == []


def test_the_kf_in_assignment_kf_blind_stretch_is_inside_the_bound():
    sc = load_scenario("assignment_kf")
    s = Session(sc, ["kf"])
    bound = LiveBound(sc)
    s.on_step.append(bound.feed)
    s.toggle_autopilot()
    for _ in range(round(16.0 / sc.dt)):
        s.tick()
    assert bound.valid
    b_pos = bound.sigmas()[0]
    assert np.isfinite(b_pos)
    assert inside_the_bound(s, b_pos) == ["kf"]
