"""Dead reckoning's lean prediction is the filter template's, bit for bit, on
every shipped scenario, and a noise model of one's own still goes through its process_cov."""

import dataclasses
import types

import numpy as np
import pytest

from beacon_sim.core.motion import MotionNoise
from beacon_sim.core.resources import shipped_scenarios
from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.hosting.loading import build_filter
from beacon_sim.templates import render_template


def _template_class():
    mod = types.ModuleType("lean_dr_template")
    exec(render_template("MyFilter", "my_filter.py"), mod.__dict__)
    return mod.MyFilter


@pytest.mark.parametrize("name", shipped_scenarios())
def test_dead_reckoning_is_the_template_bit_for_bit(name):
    sc = load_scenario(name)
    dr = build_filter("dead_reckoning", sc, 0)
    tm = _template_class()(dr.ctx)
    dr.reset(None)
    tm.reset(None)
    for st in Simulation(sc, 2).run(min(sc.duration, 30.0)):
        for f in (dr, tm):
            f.predict(st.control, st.dt)
            f.update(st.measurements)
        (m1, c1), (m2, c2) = dr.estimate(), tm.estimate()
        assert np.array_equal(m1, m2) and np.array_equal(c1, c2)


class DoubledNoise(MotionNoise):
    def process_cov(self, pose, v, omega, dt):
        return 2.0 * super().process_cov(pose, v, omega, dt)


def test_a_noise_model_of_ones_own_is_asked_for_its_process_cov():
    sc = load_scenario("default")
    dr = build_filter("dead_reckoning", sc, 0)
    noise = DoubledNoise(**{f.name: getattr(dr.ctx.motion_noise, f.name)
                            for f in dataclasses.fields(MotionNoise)})
    dr.ctx = dataclasses.replace(dr.ctx, motion_noise=noise)
    tm = _template_class()(dr.ctx)
    dr.reset(None)
    tm.reset(None)
    for st in Simulation(sc, 0).run(5.0):
        dr.predict(st.control, st.dt)
        tm.predict(st.control, st.dt)
    assert np.array_equal(dr.estimate()[1], tm.estimate()[1])
