"""Beacons behind walls: a beacon sensor in a world with walls does not see a
beacon whose line of sight crosses an occupied cell (``occluded_by_walls``, on by default);
the simulation, the batched Monte Carlo path and the PCRB share that visibility
(``sensors.visible_mask``); in worlds without walls nothing changes, bit for bit."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from beacon_sim.core.batch_simulation import BatchSimulation
from beacon_sim.core.occupancy import from_walls
from beacon_sim.core.raycast import line_of_sight
from beacon_sim.core.resources import shipped_scenarios
from beacon_sim.core.scenario import Scenario, ScenarioError, load_scenario, parse_scenario
from beacon_sim.core.sensors import sense, visible_beacons, visible_mask
from beacon_sim.core.simulation import Simulation
from beacon_sim.evaluation.pcrb import measurement_information

ROOM = [(0.0, 0.0), (10.0, 0.0), (10.0, 6.0), (0.0, 6.0), (0.0, 0.0)]
PARTITION = [(5.0, 0.0), (5.0, 4.0)]          # a wall from the floor up to y = 4: a gap above


def test_line_of_sight_on_a_hand_built_map():
    grid = from_walls((0, 0, 10, 6), 0.05, segments=[ROOM, PARTITION],
                      polygons=[[(7.0, 1.0), (9.0, 1.0), (9.0, 2.0), (7.0, 2.0)]])  # a block
    o = np.array([2.0, 2.0])
    targets = np.array([
        [8.0, 2.0],     # behind the partition: hidden
        [3.0, 5.0],     # same side, open: seen
        [6.0, 5.5],     # over the partition's top (y = 4.6 at x = 5), through the gap: seen
        [5.0, 2.0],     # on the partition itself: seen from its free side
        [8.0, 1.5],     # inside the block, behind the partition: hidden
        [2.0, 2.0],     # at the sensor: seen
    ])
    got = line_of_sight(grid, np.tile(o, (len(targets), 1)), targets)
    assert got.tolist() == [False, True, True, True, False, True]
    # From beyond the partition, the block's own face cell is seen, its middle is not.
    o2 = np.tile([6.0, 1.5], (2, 1))
    assert line_of_sight(grid, o2, [[7.0, 1.5], [8.0, 1.5]]).tolist() == [True, False]


def _world_dict(occluded=None, walls=True):
    sensor = {"name": "beacons", "kind": "range_bearing", "period": 0.1}
    if occluded is not None:
        sensor["occluded_by_walls"] = occluded
    world = {"bounds": [0.0, 0.0, 10.0, 6.0],
             "beacons": [{"id": 1, "x": 8.0, "y": 2.0}, {"id": 2, "x": 3.0, "y": 5.0},
                         {"id": 3, "x": 6.0, "y": 5.5}]}
    if walls:
        world["walls"] = {"resolution": 0.05,
                          "segments": [[list(p) for p in ROOM], [list(p) for p in PARTITION]]}
    return {"name": "two_sides", "dt": 0.1, "world": world,
            "robot": {"initial_pose": [2.0, 2.0, 0.0], "radius": 0.2},
            "sensors": [sensor], "driver": {"kind": "constant", "v": 0.0, "omega": 0.0}}


def test_a_beacon_behind_a_wall_is_not_sensed_one_in_sight_is():
    sc = parse_scenario(_world_dict(), "<test>")
    spec = sc.sensors[0]
    assert spec.occluded_by_walls
    pose = np.array(sc.initial_pose)
    assert visible_beacons(spec, pose, sc.world).tolist() == [False, True, True]
    m = sense(spec, pose, sc.world, np.random.default_rng(0))
    assert sorted(m.beacon_ids.tolist()) == [2, 3]
    # Off: seen through the wall, as before occlusion (0.3.0).
    off = parse_scenario(_world_dict(occluded=False), "<test>")
    assert visible_beacons(off.sensors[0], pose, off.world).all()
    m = sense(off.sensors[0], pose, off.world, np.random.default_rng(0))
    assert sorted(m.beacon_ids.tolist()) == [1, 2, 3]


def test_the_simulation_the_batched_runs_and_the_pcrb_share_the_visibility():
    sc = parse_scenario(_world_dict(), "<test>")
    spec = sc.sensors[0]
    poses = np.array([[2.0, 2.0, 0.0], [8.0, 3.0, 1.0], [5.5, 5.0, -2.0]])
    vis = visible_mask(spec, poses, sc.world)
    for pose, row in zip(poses, vis, strict=True):
        assert visible_beacons(spec, pose, sc.world).tolist() == row.tolist()
    # The PCRB: a hidden beacon adds nothing; its information is that of the seen ones.
    info = measurement_information(spec, poses, sc.world.beacon_xy, sc.world)
    for i in range(len(poses)):
        alone = measurement_information(spec, poses[i:i + 1], sc.world.beacon_xy[vis[i]])[0]
        np.testing.assert_allclose(info[i], alone, rtol=1e-12, atol=1e-12)
    through = measurement_information(spec, poses, sc.world.beacon_xy)   # no walls given
    assert np.trace(through[0]) > np.trace(info[0])
    # The batched Monte Carlo path reads what single runs read, walls included.
    moving = _world_dict()
    moving["driver"] = {"kind": "constant", "v": 0.3, "omega": 0.2}
    moving["robot"]["motion_noise"] = {"v_std": 0.02, "omega_std": 0.02}
    sc = parse_scenario(moving, "<test>")
    batch = BatchSimulation(sc, [1, 2])
    singles = [Simulation(sc, seed=s) for s in (1, 2)]
    hidden = 0
    for _ in range(80):
        batch.advance()
        for sim in singles:
            st = sim.step()
            seen = {int(i) for m in st.measurements for i in m.beacon_ids}
            hidden += 1 not in seen
    assert hidden > 0
    assert batch.truth_checksums() == [s.truth_checksum for s in singles]
    assert batch.readings_checksums() == [s.readings_checksum for s in singles]


def _digests(sc: Scenario, seconds: float = 20.0) -> tuple[str, str]:
    sim = Simulation(sc)
    sim.run(seconds)
    return sim.truth_checksum, sim.readings_checksum


@pytest.mark.parametrize("name", [n for n in ["default", "krejsa_bearing_only", "ulps_circle",
                                              "sparse_kidnap", "lookalike_beacons"]])
def test_without_walls_occlusion_changes_nothing_bit_for_bit(name):
    if name not in shipped_scenarios():
        pytest.skip(f"{name} is not shipped")
    sc = load_scenario(name)
    assert sc.world.grid is None and all(s.occluded_by_walls for s in sc.sensors)
    off = replace(sc, sensors=tuple(replace(s, occluded_by_walls=False) for s in sc.sensors))
    assert _digests(sc) == _digests(off)


def test_a_wall_less_world_reads_the_same_with_the_key_on_or_off():
    on = parse_scenario(_world_dict(occluded=True, walls=False), "<test>")
    off = parse_scenario(_world_dict(occluded=False, walls=False), "<test>")
    assert _digests(on, 5.0) == _digests(off, 5.0)


def test_the_key_must_be_true_or_false():
    with pytest.raises(ScenarioError, match="occluded_by_walls"):
        parse_scenario(_world_dict(occluded="yes"), "<test>")
    assert math.isfinite(parse_scenario(_world_dict(occluded=False), "<test>").dt)
