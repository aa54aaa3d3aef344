"""Worlds with walls: ``world.map`` / ``[world.walls]`` in a scenario, the bumper
against walls, the range_finder sensor, and the three shipped map scenarios."""

from __future__ import annotations

import math

import numpy as np
import pytest
from portable_checksums import TICKS, documented_checksums

from beacon_sim.core.occupancy import FREE, OCCUPIED, OccupancyGrid, from_walls, load_map, save_map
from beacon_sim.core.raycast import scan
from beacon_sim.core.scenario import ScenarioError, load_scenario, parse_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.core.types import Control

ROOM = """
name = "room"
description = "a test room"
dt = 0.1
duration = 5.0
[world]
{world}
[robot]
initial_pose = {pose}
radius = 0.2
motion_noise = {{ v_std = 0.0, v_frac = 0.0, omega_std = 0.0, omega_frac = 0.0 }}
[[sensors]]
name = "laser"
kind = "range_finder"
period = 0.1
n_beams = {beams}
fov = 6.283185307179586
max_range = 5.0
{model}
"""

WALLS = """bounds = [0.0, 0.0, 4.0, 2.0]
[world.walls]
resolution = 0.05
segments = [[[0.0, 0.0], [4.0, 0.0], [4.0, 2.0], [0.0, 2.0], [0.0, 0.0]]]"""

SHARP = "z_hit = 1.0\nz_short = 0.0\nz_max = 0.0\nz_rand = 0.0\nsigma_hit = 1e-6"


def write_room(tmp_path, world=WALLS, pose="[2.0, 1.0, 0.0]", beams=4, model=SHARP):
    path = tmp_path / "room.toml"
    path.write_text(ROOM.format(world=world, pose=pose, beams=beams, model=model))
    return path


# ----------------------------------------------------------------------------- scenario files

def test_walls_in_toml_make_the_worlds_grid(tmp_path):
    sc = load_scenario(write_room(tmp_path))
    g = sc.world.grid
    assert isinstance(g, OccupancyGrid) and g.shape == (40, 80) and g.resolution == 0.05
    assert g.occupied[0].all() and g.occupied[-1].all() and g.occupied[:, 0].all() and g.occupied[:, -1].all()
    assert not g.occupied[1:-1, 1:-1].any()


def test_a_map_server_map_relative_to_the_scenario(tmp_path):
    """world.map names a YAML beside the scenario; the bounds default to the map's extent,
    the origin and negate of the file are honoured (the round trip through a scenario)."""
    cells = np.full((20, 30), FREE, dtype=np.int8)
    cells[0, :] = cells[-1, :] = cells[:, 0] = cells[:, -1] = OCCUPIED
    cells[5:8, 10:12] = OCCUPIED
    grid = OccupancyGrid(cells, 0.1, (-1.0, 2.0, 0.0))
    (tmp_path / "maps").mkdir()
    save_map(grid, tmp_path / "maps" / "floor.yaml", negate=1)
    sc = load_scenario(write_room(tmp_path, world='map = "maps/floor.yaml"', pose="[0.5, 3.0, 0.0]"))
    assert sc.world.bounds == pytest.approx((-1.0, 2.0, 2.0, 4.0))
    np.testing.assert_array_equal(sc.world.grid.cells, cells)
    assert sc.world.grid.origin == (-1.0, 2.0, 0.0)


@pytest.mark.parametrize("world, words", [
    ('map = "nowhere.yaml"', "world.map = 'nowhere.yaml'"),
    ('map = "m.yaml"\n[world.walls]\nresolution = 0.1', "world.map and world.walls"),
    ('bounds = [0.0, 0.0, 4.0, 2.0]\n[world.walls]\nsegments = [[[0.0, 0.0]]]', "world.walls.segments"),
    ('bounds = [0.0, 0.0, 4.0, 2.0]\n[world.walls]\nresolution = 0.0', "world.walls.resolution"),
    ('bounds = [0.0, 0.0, 4.0, 2.0]\n[world.walls]\nsegment = []', "did you mean 'world.walls.segments'"),
    ('bounds = [0.0, 0.0, 4.0, 2.0]', "a range_finder sensor needs walls"),
])
def test_bad_map_tables_name_the_file_and_key(tmp_path, world, words):
    path = write_room(tmp_path, world=world)
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    msg = str(info.value)
    assert str(path) in msg and words in msg and "\n" not in msg


def test_the_robot_may_not_start_in_a_wall(tmp_path):
    with pytest.raises(ScenarioError, match=r"robot\.initial_pose = \[0\.1, 1\.0, 0\.0\]: expected a "
                                            r"position at least robot\.radius = 0\.2 m from every wall"):
        load_scenario(write_room(tmp_path, pose="[0.1, 1.0, 0.0]"))


@pytest.mark.parametrize("key, value, words", [
    ("max_range", "inf", "a finite maximum range"),
    ("n_beams", "0", "an integer in [1, 4096]"),
    ("sigma_hit", "0.0", "sensors[0].sigma_hit"),
])
def test_bad_range_finder_keys(tmp_path, key, value, words):
    text = write_room(tmp_path).read_text()
    text = "\n".join(line for line in text.splitlines() if not line.startswith(f"{key} ="))
    path = tmp_path / "bad.toml"
    path.write_text(text + f"\n{key} = {value}\n")
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    assert words in str(info.value) and str(path) in str(info.value)


# ----------------------------------------------------------------------------- the sensor

def test_a_scan_reads_the_hand_computed_distances(tmp_path):
    """The walls of a 4 m x 2 m room fill the border cells (0.05 m): from (2, 1) facing +x,
    beams at -pi, -pi/2, 0, pi/2 end 1.95, 0.95, 1.95, 0.95 m away; the beam angles are the
    second column."""
    sim = Simulation(load_scenario(write_room(tmp_path)))
    m = sim.step(Control(0.0, 0.0)).measurements[0]
    assert m.kind == "range_finder" and m.z.shape == (4, 2)
    np.testing.assert_allclose(m.z[:, 1], [-math.pi, -math.pi / 2, 0.0, math.pi / 2])
    np.testing.assert_allclose(m.z[:, 0], [1.95, 0.95, 1.95, 0.95], atol=1e-4)
    assert m.beacon_ids.shape == (0,)      # a scan names no beacon


def test_scan_noise_follows_the_beam_model_and_replays(tmp_path):
    """With the beam model's four parts most readings lie near the ray-cast range, a few
    are short, random or at max range; the same seed gives the same readings bit for bit,
    and a beam with nothing within range reads max range unless a short or random reading
    is drawn."""
    path = write_room(tmp_path, beams=360, model="z_hit = 0.8\nz_short = 0.1\nz_max = 0.05\n"
                                                 "z_rand = 0.05\nsigma_hit = 0.02")
    sc = load_scenario(path)
    runs = []
    for _ in range(2):
        sim = Simulation(sc, seed=3)
        runs.append(np.vstack([m.z for _ in range(20) for m in sim.step(Control(0.0, 0.0)).measurements]))
    np.testing.assert_array_equal(runs[0], runs[1])
    _, truth = scan(sc.world.grid, sc.initial_pose, 360, 2 * math.pi, 5.0)
    z = runs[0][:, 0].reshape(20, 360)
    near = np.abs(z - truth) < 0.1
    assert 0.75 < near.mean() < 0.85                        # the hit share, 0.8
    assert 0.03 < (z == 5.0).mean() < 0.07                   # the max share, 0.05
    assert (z[~near] < truth[None, :].repeat(20, 0)[~near]).mean() > 0.5   # short ones dominate


def test_a_world_without_walls_in_range_reads_max_range(tmp_path):
    world = WALLS.replace("[4.0, 0.0], [4.0, 2.0], [0.0, 2.0], [0.0, 0.0]", "[0.1, 0.0]")
    world = world.replace("bounds = [0.0, 0.0, 4.0, 2.0]", "bounds = [0.0, 0.0, 40.0, 20.0]")
    sim = Simulation(load_scenario(write_room(tmp_path, world=world, pose="[20.0, 10.0, 0.0]")))
    np.testing.assert_array_equal(sim.step(Control(0.0, 0.0)).measurements[0].z[:, 0], 5.0)


# ----------------------------------------------------------------------------- the bumper

def test_walls_are_solid(tmp_path):
    """Driving at a wall: the robot stops with its disc clear of it, a bump is reported and
    the filters are told v = 0; it may turn away and drive off again."""
    world = WALLS.replace("[0.0, 0.0]]]", "[0.0, 0.0]], [[3.0, 0.0], [3.0, 2.0]]]")
    sim = Simulation(load_scenario(write_room(tmp_path, world=world, pose="[1.0, 1.0, 0.0]")))
    steps = [sim.step(Control(0.5, 0.0)) for _ in range(80)]
    xs = np.array([s.true_pose[0] for s in steps])
    assert xs.max() < 3.0 - 0.2 + 0.05 and xs.max() > 3.0 - 0.2 - 0.1   # stopped at the wall
    bumped = [s for s in steps if any(e.kind == "bump" for e in s.events)]
    assert bumped and all(s.control.v == 0.0 for s in bumped)
    for _ in range(32):                      # turn half a turn, then drive away
        sim.step(Control(0.0, math.pi / 3.2))
    away = [sim.step(Control(0.5, 0.0)) for _ in range(10)]
    assert away[-1].true_pose[0] < xs.max() - 0.3


def test_random_kidnaps_land_in_free_space():
    sc = load_scenario("office")
    rng = np.random.default_rng(5)
    for _ in range(50):
        pose = sc.world.random_pose(rng, margin=0.3)
        assert sc.world.is_free(pose, 0.3)


# ----------------------------------------------------------------------------- shipped maps

def test_beacon_worlds_keep_their_truth():
    """Worlds without walls are not touched by the map code: the truth and readings of 300
    ticks of every beacon scenario are the documented ones (docs/portability.md)."""
    documented = documented_checksums()
    for name in ("assignment_kf", "default", "global_kidnap", "krejsa_bearing_only",
                 "sparse_kidnap", "ulps_circle"):
        sc = load_scenario(name)
        assert sc.world.grid is None
        sim = Simulation(sc)
        for _ in range(TICKS):
            sim.step()
        assert (sim.truth_checksum, sim.readings_checksum) == documented[name], name


@pytest.mark.parametrize("name", ["corridor", "office", "symmetric_room"])
def test_the_map_scenarios_load_and_run(name):
    sc = load_scenario(name)
    assert sc.world.grid is not None and sc.default_filters[0] == "mcl"
    assert any(s.kind == "range_finder" for s in sc.sensors)
    sim = Simulation(sc)
    steps = sim.run(10.0)
    for s in steps:
        assert sc.world.is_free(s.true_pose, sc.robot_radius - sc.world.grid.resolution)


def test_the_office_map_file_is_the_walls_script():
    """assets/maps/office.{yaml,pgm} is what scripts/make_office_map.py writes."""
    import importlib.util
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    spec = importlib.util.spec_from_file_location("make_office_map", root / "scripts" / "make_office_map.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    segments, polygons = mod.office_walls()
    grid = from_walls(mod.BOUNDS, mod.RESOLUTION, segments=segments, polygons=polygons)
    shipped = load_map(root / "assets" / "maps" / "office.yaml")
    np.testing.assert_array_equal(shipped.cells, grid.cells)


def test_the_symmetric_room_is_symmetric_but_for_the_partition():
    g = load_scenario("symmetric_room").world.grid
    occ = g.occupied
    differ = np.argwhere(occ != occ[::-1, ::-1])
    xy = g.cell_to_world(differ)
    # only the partition (south-east) and the empty place it would mirror to (north-west)
    assert len(differ) > 0
    assert np.all(((xy[:, 0] > 6.9) & (xy[:, 1] < 1.6)) | ((xy[:, 0] < 1.1) & (xy[:, 1] > 2.4)))


def test_parse_scenario_without_a_file_reads_walls():
    """Walls need no file (parse_scenario on a dict, as the API builds scenarios)."""
    data = {"world": {"bounds": [0.0, 0.0, 2.0, 2.0],
                      "walls": {"resolution": 0.1, "polygons": [[[0.5, 0.5], [1.0, 0.5], [1.0, 1.0]]]}},
            "robot": {"initial_pose": [1.5, 1.5, 0.0]}}
    sc = parse_scenario(data, "<dict>")
    assert sc.world.grid.occupied.sum() > 0


def test_beacons_and_walls_in_one_world(tmp_path):
    """A world may hold walls and beacons: the scan sees the walls, the beacon sensor the
    beacons (this one in line of sight; walls hide beacons: tests/core/test_occlusion.py), and
    an EKF ignores the scans."""
    world = WALLS.replace("bounds = [0.0, 0.0, 4.0, 2.0]",
                          "bounds = [0.0, 0.0, 4.0, 2.0]\nbeacons = [{ id = 1, x = 3.0, y = 1.5 }]")
    text = write_room(tmp_path, world=world).read_text() + (
        '\n[[sensors]]\nname = "beacons"\nkind = "range_bearing"\nperiod = 0.1\n')
    path = tmp_path / "both.toml"
    path.write_text(text)
    sc = load_scenario(path)
    sim = Simulation(sc)
    kinds = {m.kind for m in sim.step(Control(0.0, 0.0)).measurements}
    assert kinds == {"range_finder", "range_bearing"}
    from beacon_sim.hosting.loading import build_filter

    ekf = build_filter("ekf", sc, 1)
    before = ekf.estimate()[0]
    st = sim.step(Control(0.0, 0.0))
    ekf.predict(st.control, st.dt)
    ekf.update([m for m in st.measurements if m.kind == "range_finder"])
    np.testing.assert_array_equal(ekf.estimate()[0], before)
    ekf.update(st.measurements)                      # the beacon reading moves it
    assert not np.array_equal(ekf.estimate()[0], before)


def test_batched_runs_meet_the_walls_as_single_runs_do(tmp_path):
    """core/batch_simulation (Monte Carlo's fast path) stops at walls bit for bit as
    Simulation.step does: a robot driven at a wall, two seeds."""
    from beacon_sim.core.batch_simulation import BatchSimulation

    world = WALLS.replace("[0.0, 0.0]]]", "[0.0, 0.0]], [[3.0, 0.0], [3.0, 2.0]]]")
    text = write_room(tmp_path, world=world, pose="[1.0, 1.0, 0.0]").read_text()
    text = text.replace('[robot]', '[driver]\nkind = "constant"\nv = 0.5\nomega = 0.05\n\n[robot]')
    text = text.replace("v_std = 0.0, v_frac = 0.0", "v_std = 0.02, v_frac = 0.1")
    path = tmp_path / "drive.toml"
    path.write_text(text)
    sc = load_scenario(path)
    batch = BatchSimulation(sc, [1, 2])
    singles = [Simulation(sc, seed=s) for s in (1, 2)]
    bumps = 0
    for _ in range(60):
        tick = batch.advance()
        for i, sim in enumerate(singles):
            st = sim.step()
            assert tick.pose[i].tobytes() == st.true_pose.tobytes()
            bumps += any(e.kind == "bump" for e in st.events)
    assert bumps > 10
    assert batch.truth_checksums() == [s.truth_checksum for s in singles]
