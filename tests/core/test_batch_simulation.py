"""core/batch_simulation.py: R runs stepped together are, bit for bit, R single runs (truth,
commands, readings, events, both checksums) on every shipped scenario; the tick as arrays
(``advance``) and its packing (``SlotPacker.pack_tick``) are, bit for bit, the Step objects
and their packing (``pack``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from beacon_sim.core.batch_simulation import BatchSimulation
from beacon_sim.core.resources import shipped_scenarios
from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.evaluation.association_metrics import with_known_correspondence


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
    if any(s.correspondence != "known" for s in sc.sensors):
        # The batch tells every ID (runs without IDs are never batched), so it is
        # the single runs with the IDs told
        sc = with_known_correspondence(sc)
    seeds = [0, 1, 7, 12345]
    duration = min(sc.duration, 60.0)
    # One batch and one single run per seed, each simulated once: the steps are compared
    # tick by tick, then the checksums the two kept along the way (a Simulation's step
    # updates them as its run() does).
    bs = BatchSimulation(sc, seeds)
    batch = bs.run(duration)
    for seed, steps, truth, readings in zip(seeds, batch, bs.truth_checksums(), bs.readings_checksums(),
                                            strict=True):
        sim = Simulation(sc, seed)
        for st in steps:
            _same_step(st, sim.step())
        assert (truth, readings) == (sim.truth_checksum, sim.readings_checksum)


def _everything():
    """default with outliers, a field of view, a bearing compass, a blackout, a noise burst,
    a random kidnap and a driver into the wall."""
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
    return parse_scenario(data, "test", name="everything")


def test_outliers_field_of_view_blackouts_bursts_and_walls_too():
    sc = _everything()
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


def _same_stacked(a, b):
    assert (a is None) == (b is None)
    if a is None:
        return
    for x, y in ((a.z, b.z), (a.r, b.r), (a.valid, b.valid), (a.angle, b.angle)):
        assert x.shape == y.shape and x.dtype == y.dtype and x.tobytes() == y.tobytes()
    assert a.angle_sel == b.angle_sel if isinstance(a.angle_sel, slice) else \
        np.array_equal(a.angle_sel, b.angle_sel)
    assert [blk[:3] for blk in a.blocks] == [blk[:3] for blk in b.blocks]


@pytest.mark.parametrize("name", [*shipped_scenarios(), "everything"])
def test_the_tick_as_arrays_is_the_steps_and_packs_the_same_bits(name):
    """advance() (arrays) and step() (objects) on two batches of the same seeds: the same
    steps, poses, commands and kidnaps; pack_tick of the arrays is pack of the Measurements,
    bit for bit (z, r, valid); the checksums agree, also when the two ways are mixed."""
    from beacon_sim.filters.gaussian.measurements import KINDS as SLOT_KINDS
    from beacon_sim.filters.gaussian.measurements import SlotPacker

    sc = _everything() if name == "everything" else load_scenario(name)
    seeds = [0, 3, 12345]
    arrays, objects, mixed = (BatchSimulation(sc, seeds) for _ in range(3))
    # kinds the Gaussian filters have no slots for (weighed by their record's model, never
    # batched: BatchableFilter.batch_blocker) are not packed
    slots = all(s.kind in SLOT_KINDS or s.kind == "range_finder" for s in sc.sensors)
    packer = SlotPacker(sc.world, sc.model_sensors) if slots else None
    packed = 0
    for k in range(round(min(sc.duration, 40.0) / sc.dt)):
        tick = arrays.advance()
        steps = objects.step()
        (mixed.advance().steps() if k % 2 else mixed.step())
        for i, (a, b) in enumerate(zip(tick.steps(), steps, strict=True)):
            _same_step(a, b)
            assert tick.pose[i].tobytes() == b.true_pose.tobytes()
            assert (float(tick.v[i]), float(tick.omega[i])) == (b.control.v, b.control.omega)
            assert bool(tick.kidnapped[i]) == b.kidnapped
        if packer is not None:
            st = packer.pack_tick(tick)
            _same_stacked(st, packer.pack([s.measurements for s in steps]))
            packed += st is not None
    # a scan has no Gaussian slots: a scenario with only a range finder packs nothing
    assert packed > 0 or packer is None or all(s.kind == "range_finder" for s in sc.sensors)
    for bs in (arrays, mixed):
        assert bs.truth_checksums() == objects.truth_checksums()
        assert bs.readings_checksums() == objects.readings_checksums()
        assert [s.pose.tobytes() for s in bs.sims] == [s.pose.tobytes() for s in objects.sims]


def test_truth_checksums_over_long_runs_and_without_readings_checksums():
    """The truth checksum is hashed from the stored poses in chunks; a batch made without
    readings checksums says so instead of giving a wrong one."""
    sc = load_scenario("default")
    bs = BatchSimulation(sc, [5, 6], readings_checksums=False)
    for _ in range(2500):   # more than one chunk of stored poses
        bs.advance()
    for seed, got in zip((5, 6), bs.truth_checksums(), strict=True):
        sim = Simulation(sc, seed)
        sim.run(2500 * sc.dt)
        assert got == sim.truth_checksum
    with pytest.raises(RuntimeError):
        bs.readings_checksums()


def test_pack_tick_reports_a_sensor_or_beacon_without_slots():
    """As pack does: a sensor without slots, a reading of a beacon not on the filters' map;
    readings of the other beacons pack as pack packs them."""
    from beacon_sim.core.world import World
    from beacon_sim.filters.base import FilterError
    from beacon_sim.filters.gaussian.measurements import SlotPacker

    sc = load_scenario("default")
    fewer = SlotPacker(World(sc.world.bounds, sc.world.beacons[1:]), sc.model_sensors)  # no beacon 1
    bs = BatchSimulation(sc, [1, 2])
    raised = compared = 0
    for _ in range(400):
        tick = bs.advance()
        if not tick.readings:
            continue
        with pytest.raises(FilterError, match="no slots"):
            SlotPacker(sc.world, []).pack_tick(tick)
        if tick.readings[0].seen[:, 0].any():
            with pytest.raises(FilterError, match="not on the map"):
                fewer.pack_tick(tick)
            raised += 1
        else:
            _same_stacked(fewer.pack_tick(tick), fewer.pack([tick.measurements(i) for i in range(2)]))
            compared += 1
    assert raised and compared


def test_steer_on_arrays_is_steer_towards_bit_for_bit():
    """The batched drivers' steering: every run's (v, omega) equal to drivers.steer_towards's
    floats, on random poses and goals and on the edges (headings at +-pi, goals straight
    behind, the turn rate exactly at its limit, a goal on the robot, NaN)."""
    from beacon_sim.core.batch_simulation import steer
    from beacon_sim.core.drivers import steer_towards

    rng = np.random.default_rng(3)
    n = 20000
    pose = np.column_stack([rng.uniform(-5, 5, n), rng.uniform(-5, 5, n), rng.uniform(-np.pi, np.pi, n)])
    goal = rng.uniform(-5, 5, (n, 2))
    pose[:50, 2] = np.pi - np.ldexp(1.0, -rng.integers(1, 52, 50))
    pose[50:100, 2] = -np.pi
    goal[100:150] = pose[100:150, :2] - rng.uniform(0.1, 1, (50, 1)) * np.column_stack(
        [np.cos(pose[100:150, 2]), np.sin(pose[100:150, 2])])           # straight behind
    goal[150:160] = pose[150:160, :2]                                    # on the robot
    pose[160:170] = np.nan
    for speed, gain, max_omega in ((0.4, 2.0, 1.5), (0.3, 1.0, 0.0), (1.0, 3.0, np.pi)):
        if max_omega:   # turn rate exactly at the limit: err = +-max_omega / gain
            pose[170:180, 2] = np.arctan2(goal[170:180, 1] - pose[170:180, 1],
                                          goal[170:180, 0] - pose[170:180, 0]) - max_omega / gain
        v, w = steer(pose, goal, speed, gain, max_omega)
        for i in range(n):
            c = steer_towards(pose[i].tolist(), goal[i].tolist(), speed, gain, max_omega)
            assert np.float64(c.v).tobytes() == v[i].tobytes(), i
            assert np.float64(c.omega).tobytes() == w[i].tobytes(), i
