"""core/batch_simulation.py: R runs stepped together are, bit for bit, R single runs (truth,
commands, readings, events, both checksums) on every shipped scenario."""

from __future__ import annotations

import math

import numpy as np
import pytest

from beacon_sim.core.batch_simulation import BatchSimulation
from beacon_sim.core.resources import shipped_scenarios
from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.simulation import Simulation


def _same_step(a, b):
    assert (a.tick, a.time, a.dt) == (b.tick, b.time, b.dt)
    assert a.true_pose.tobytes() == b.true_pose.tobytes()
    assert a.control == b.control
    assert len(a.measurements) == len(b.measurements)
    for ma, mb in zip(a.measurements, b.measurements, strict=True):
        assert (ma.sensor, ma.kind) == (mb.sensor, mb.kind)
        assert ma.z.shape == mb.z.shape and ma.z.tobytes() == mb.z.tobytes()
        assert np.array_equal(ma.beacon_ids, mb.beacon_ids)
        assert (math.isnan(ma.hdop) and math.isnan(mb.hdop)) or ma.hdop == mb.hdop
    assert [(e.kind, e.tick, e.time, e.detail) for e in a.events] == \
        [(e.kind, e.tick, e.time, e.detail) for e in b.events]
    for ea, eb in zip(a.events, b.events, strict=True):
        for pa, pb in ((ea.pose_before, eb.pose_before), (ea.pose_after, eb.pose_after)):
            assert (pa is None and pb is None) or np.asarray(pa).tobytes() == np.asarray(pb).tobytes()


@pytest.mark.parametrize("name", shipped_scenarios())
def test_batched_runs_are_the_single_runs_bit_for_bit(name):
    sc = load_scenario(name)
    seeds = [0, 1, 7, 12345]
    duration = min(sc.duration, 60.0)
    batch = BatchSimulation(sc, seeds).run(duration)
    for seed, steps in zip(seeds, batch, strict=True):
        sim = Simulation(sc, seed)
        for st in steps:
            _same_step(st, sim.step())
    bs = BatchSimulation(sc, seeds)
    bs.run(duration)
    for seed, truth, readings in zip(seeds, bs.truth_checksums(), bs.readings_checksums(), strict=True):
        sim = Simulation(sc, seed)
        sim.run(duration)
        assert (truth, readings) == (sim.truth_checksum, sim.readings_checksum)


def test_outliers_field_of_view_blackouts_bursts_and_walls_too():
    import tomllib

    from beacon_sim.core.resources import scenario_dir
    from beacon_sim.core.scenario import parse_scenario

    data = tomllib.loads((scenario_dir() / "default.toml").read_text())
    s = data["sensors"][0]
    s.update(outlier_rate=0.2, fov=2.0, max_range=6.0)
    data["sensors"].append({"name": "compass", "kind": "bearing", "period": 0.2, "bearing_std": 0.1,
                            "outlier_rate": 0.3, "detection_prob": 0.7})
    data["events"] = [{"kind": "blackout", "time": 3.0, "duration": 2.0, "sensors": ["beacons"]},
                      {"kind": "noise_burst", "time": 6.0, "duration": 2.0, "v_std": 0.3, "omega_std": 0.5},
                      {"kind": "kidnap", "time": 9.0, "random": True}]
    data["driver"] = {"kind": "constant", "v": 0.8, "omega": 0.05}   # into the wall and along it
    sc = parse_scenario(data, "test", name="everything")
    seeds = list(range(6))
    bs = BatchSimulation(sc, seeds)
    batch = bs.run(30.0)
    bumps = 0
    for seed, steps in zip(seeds, batch, strict=True):
        sim = Simulation(sc, seed)
        for st in steps:
            _same_step(st, sim.step())
            bumps += sum(e.kind == "bump" for e in st.events)
        assert sim.truth_checksum == bs.sims[seeds.index(seed)].truth_checksum
    assert bumps > 0
