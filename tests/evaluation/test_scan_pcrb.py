"""The PCRB of a range finder's scan: each beam's range derivative from the wall's
normal (core/scan_jacobian.py) against slopes of the ray cast itself on hand-built maps,
the dropped beams (misses, grazing hits, rays from inside a wall), the scan's information,
and the bound along paths: finite and below mcl in the shipped map worlds, growing along a
featureless corridor but not across it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from beacon_sim.core.beam_model import RangeModelParams
from beacon_sim.core.occupancy import FREE, OCCUPIED, OccupancyGrid, from_walls
from beacon_sim.core.raycast import beam_angles, expected_ranges
from beacon_sim.core.scan_jacobian import MAX_INCIDENCE, scan_information, scan_jacobian
from beacon_sim.core.scenario import load_scenario, parse_scenario
from beacon_sim.core.sensors import SensorSpec
from beacon_sim.core.world import World
from beacon_sim.evaluation.montecarlo import run_monte_carlo
from beacon_sim.evaluation.pcrb import measurement_information, pcrb
from beacon_sim.evaluation.summary import evaluate

ROOM = [(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0), (0.0, 0.0)]


def _slopes(grid, pose, rel, h, n=41, max_range=20.0):
    """Least-squares slopes (B, 3) of the ray-cast ranges against offsets in [-h_i, h_i]
    of each pose coordinate: the ray cast's derivative at the scale of the offsets (a
    staircase's sawtooth averages out over a few cells)."""
    out = np.empty((len(rel), 3))
    for i in range(3):
        off = np.linspace(-h[i], h[i], n)
        poses = np.tile(pose, (n, 1))
        poses[:, i] += off
        r = expected_ranges(grid, poses, rel, max_range)
        A = np.column_stack([off, np.ones(n)])
        out[:, i] = np.linalg.lstsq(A, r, rcond=None)[0][0]
    return out


def test_axis_aligned_walls_the_jacobian_is_the_ray_casts_derivative():
    grid = from_walls((0, 0, 10, 10), 0.01, segments=[ROOM])
    pose = np.array([3.0, 4.0, 0.2])
    rel = np.radians([0.0, 30.0, 60.0, 100.0, 150.0, 180.0, -120.0, -60.0])
    r, J, ok = scan_jacobian(grid, pose[None], rel, 20.0)
    assert ok.all()
    fd = _slopes(grid, pose, rel, (0.005, 0.005, 0.001))
    np.testing.assert_allclose(J[0], fd, rtol=1e-5, atol=1e-6)  # curvature over h
    # The analytic form at normal incidence: the beam along +x hits x = 10 - 0.01 (the
    # wall's cells), dr/dx = -1, dr/dy = 0.
    r, J, ok = scan_jacobian(grid, np.array([[3.0, 4.0, 0.0]]), [0.0], 20.0)
    np.testing.assert_allclose(r[0, 0], 6.99, atol=1e-9)
    np.testing.assert_allclose(J[0, 0], [-1.0, 0.0, 0.0], atol=1e-12)


@pytest.mark.parametrize("pose", [(6.0, 4.0, -math.pi / 4), (6.03, 3.71, -0.5)])
def test_a_diagonal_wall_uses_the_walls_normal_not_the_staircases(pose):
    """A solid 45-degree wall (a filled triangle: no gaps at the staircase's corners)."""
    grid = from_walls((0, 0, 10, 10), 0.01, segments=[ROOM],
                      polygons=[[(5.0, 0.0), (10.0, 0.0), (10.0, 5.0)]])
    pose = np.array(pose)
    rel = np.radians([-30.0, 0.0, 20.0, 40.0])
    r, J, ok = scan_jacobian(grid, pose[None], rel, 20.0)
    assert ok.all()
    fd = _slopes(grid, pose, rel, (0.1, 0.1, 0.02), n=81)
    np.testing.assert_allclose(J[0, :, :2], fd[:, :2], atol=0.02)
    np.testing.assert_allclose(J[0, :, 2], fd[:, 2], atol=0.01 * r[0].max())
    # The staircase's own faces would give dr/dx or dr/dy alone: the wall's normal mixes
    # both equally (45 degrees).
    np.testing.assert_allclose(np.abs(J[0, :, 0]), np.abs(J[0, :, 1]), rtol=1e-9)


def test_a_thirty_degree_wall_within_its_fitted_normal():
    grid = from_walls((0, 0, 10, 10), 0.01, segments=[ROOM],
                      polygons=[[(2.0, 0.0), (10.0, 0.0), (10.0, 8.0 / math.sqrt(3.0))]])
    pose = np.array([4.0, 5.0, -1.2])
    rel = np.radians([-30.0, 0.0, 20.0, 40.0])
    r, J, ok = scan_jacobian(grid, pose[None], rel, 20.0)
    assert ok.all()
    fd = _slopes(grid, pose, rel, (0.1, 0.1, 0.02), n=81)
    # The normal is fitted to the staircase's surface cells to a degree or two.
    np.testing.assert_allclose(J[0, :, :2], fd[:, :2], atol=0.04 * np.abs(fd[:, :2]).max())
    np.testing.assert_allclose(J[0, :, 2], fd[:, 2], atol=0.04 * r[0].max())


def test_grazing_missing_and_inside_the_wall_beams_are_dropped():
    grid = from_walls((0, 0, 10, 10), 0.01, segments=[ROOM])
    # From (1, 1) the beam at heading a < 0 hits the floor wall (y = 0.01) at incidence
    # 90 - |a| degrees, before x = 10.
    pose = np.array([1.0, 1.0, 0.0])
    steep, grazing = math.radians(-60.0), math.radians(-8.0)   # incidence 30 and 82 degrees
    r, J, ok = scan_jacobian(grid, pose[None], [steep, grazing], 20.0)
    assert ok[0].tolist() == [True, False]
    assert np.all(J[0, 1] == 0.0) and np.all(np.isfinite(J))
    fd = _slopes(grid, pose, [steep], (0.005, 0.005, 0.001))
    np.testing.assert_allclose(J[0, 0], fd[0], rtol=1e-6, atol=1e-6)
    # Just inside the limit is kept, just outside is not.
    a_in = -(0.5 * math.pi - MAX_INCIDENCE) - 0.01
    a_out = -(0.5 * math.pi - MAX_INCIDENCE) + 0.01
    assert scan_jacobian(grid, pose[None], [a_in, a_out], 20.0)[2][0].tolist() == [True, False]
    # A miss (nothing within max_range) and a ray starting inside a wall carry nothing.
    r, J, ok = scan_jacobian(grid, np.array([[5.0, 5.0, 0.0], [0.005, 5.0, 0.0]]), [0.0], 3.0)
    assert r[0, 0] == 3.0 and r[1, 0] == 0.0 and not ok.any() and np.all(J == 0.0)


def test_a_beam_along_a_grid_line_stays_finite():
    """A beam running exactly along the floor wall's face (the half-open convention puts it
    in the free cells above it) grazes it all the way to the end wall, where it hits the
    corner of two walls: the corner's face normal (the end wall's, -x), so dr/dx = -1 and
    nothing is infinite (the derivative is one-sided there: below, the floor)."""
    grid = from_walls((0, 0, 10, 10), 0.01, segments=[ROOM])
    r, J, ok = scan_jacobian(grid, np.array([[5.0, 0.01, 0.0]]), [0.0, math.pi], 20.0)
    assert np.all(np.isfinite(J)) and np.all(np.isfinite(r))
    np.testing.assert_allclose(r[0], [4.99, 4.99], atol=1e-9)  # the walls are the edge cells
    assert ok[0].all()
    np.testing.assert_allclose(J[0], [[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]], atol=1e-12)


def test_small_pillars_and_corners_take_the_face_they_are_hit_on():
    """A 0.4 m pillar (8 cells, smaller than the normal's fit window): no line to fit, so
    each beam takes the face it enters through, the ray cast's own derivative."""
    grid = from_walls((0, 0, 10, 10), 0.05, segments=[ROOM],
                      polygons=[[(5.0, 5.0), (5.4, 5.0), (5.4, 5.4), (5.0, 5.4)]])
    pose = np.array([3.03, 4.11, 0.1])
    # Beams at the pillar's west face and its south face (from below and to the left).
    rel = np.array([math.atan2(5.2 - 4.11, 5.0 - 3.03), math.atan2(5.35 - 4.11, 5.0 - 3.03)]) - 0.1
    low = np.array([4.1, 3.0, 0.0])
    rel_low = np.array([math.atan2(5.0 - 3.0, 5.23 - 4.1)])   # not at a cell corner
    for p, a in ((pose, rel), (low, rel_low)):
        r, J, ok = scan_jacobian(grid, p[None], a, 20.0)
        assert ok.all() and np.all(r < 3.0)
        fd = _slopes(grid, p, a, (0.002, 0.002, 0.0005), n=21)
        np.testing.assert_allclose(J[0], fd, rtol=1e-4, atol=1e-6)


def test_a_rotated_map_s_walls_are_rotated_normals():
    """A map whose origin has a yaw (map_server's third origin value): walls along the grid's
    axes are at 0.4 rad in the world; the normals turn with them."""
    cells = np.full((200, 300), FREE, dtype=np.int8)
    cells[:3] = cells[-3:] = OCCUPIED
    cells[:, :3] = cells[:, -3:] = OCCUPIED
    cells[80:100, 150:160] = OCCUPIED                       # a pillar
    grid = OccupancyGrid(cells, 0.02, (1.0, -0.5, 0.4))
    pose = np.array([2.5, 1.5, 0.3])
    rel = np.radians(np.arange(-170.0, 180.0, 20.0))
    r, J, ok = scan_jacobian(grid, pose[None], rel, 20.0)
    assert ok.all() and np.all(r < 4.0)                     # every beam hits inside the map
    fd = _slopes(grid, pose, rel, (0.003, 0.003, 0.0005), n=21)
    np.testing.assert_allclose(J[0], fd, rtol=1e-4, atol=1e-6)


def test_scan_information_is_z_hit_times_the_sum_of_beam_informations():
    grid = from_walls((0, 0, 10, 10), 0.05, segments=[ROOM, [(6.0, 2.0), (8.0, 7.0)]])
    poses = np.array([[3.0, 4.0, 0.2], [7.0, 8.0, -2.0]])
    model = RangeModelParams(z_hit=0.8, z_short=0.1, z_max=0.05, z_rand=0.15, sigma_hit=0.05,
                             laser_max_range=6.0)
    spec = SensorSpec("laser", "range_finder", max_range=6.0, n_beams=90, range_model=model)
    rel = beam_angles(90, 2 * math.pi)
    _, J, ok = scan_jacobian(grid, poses, rel, 6.0)
    w = model.weights[0]
    assert w == pytest.approx(0.8 / 1.1)
    want = np.stack([w / 0.05**2 * J[i][ok[i]].T @ J[i][ok[i]] for i in range(2)])
    world = World((0.0, 0.0, 10.0, 10.0), (), grid)
    got = measurement_information(spec, poses, world.beacon_xy, world)
    np.testing.assert_allclose(got, want, rtol=1e-12)
    np.testing.assert_allclose(got, scan_information(grid, poses, rel, 6.0, 0.05, w), rtol=1e-12)
    assert np.all(np.linalg.eigvalsh(got) > 0)          # a room fixes x, y and heading
    # Without walls a scan tells nothing; without the world it is refused.
    assert np.all(scan_information(None, poses, rel, 6.0, 0.05) == 0.0)
    with pytest.raises(ValueError, match="world"):
        measurement_information(spec, poses, world.beacon_xy)


def _corridor_dict(duration=30.0):
    """A long corridor with nothing in it: 40 m x 2 m, the robot driving along its axis from
    x = 5 m to 20 m; the 4 m laser never reaches its ends."""
    return {
        "name": "featureless", "dt": 0.1, "duration": duration,
        "world": {"bounds": [0.0, 0.0, 40.0, 2.0],
                  "walls": {"resolution": 0.05,
                            "segments": [[[0.0, 0.0], [40.0, 0.0], [40.0, 2.0], [0.0, 2.0],
                                          [0.0, 0.0]]]}},
        "robot": {"initial_pose": [5.0, 1.0, 0.0], "radius": 0.2,
                  "motion_noise": {"v_std": 0.02, "v_frac": 0.1, "omega_std": 0.02}},
        "sensors": [{"name": "laser", "kind": "range_finder", "period": 0.2, "n_beams": 60,
                     "max_range": 4.0, "sigma_hit": 0.03, "z_hit": 0.9, "z_short": 0.03,
                     "z_max": 0.02, "z_rand": 0.05}],
        "driver": {"kind": "constant", "v": 0.5, "omega": 0.0},
    }


def test_in_a_featureless_corridor_the_bound_grows_along_it_not_across():
    sc = parse_scenario(_corridor_dict(), "<test>")
    T = round(sc.duration / sc.dt)
    x = 5.0 + 0.5 * sc.dt * np.arange(T + 1)
    truths = np.column_stack([x, np.ones(T + 1), np.zeros(T + 1)])[None]
    controls = np.tile([0.5, 0.0], (1, T, 1))
    P = pcrb(sc, truths, controls)[0]
    assert np.all(np.isfinite(P))
    sxx, syy, sth = (np.sqrt(P[:, i, i]) for i in range(3))
    t5, t30 = round(5.0 / sc.dt) - 1, T - 1
    # Along: the walls tell nothing about x, the bound is dead reckoning's, sqrt(t) growth.
    assert sxx[t30] > 2.0 * sxx[t5]
    assert np.all(np.diff(sxx) > -1e-12)
    # Across and in heading: the side walls hold it, about a millimetre, flat.
    assert syy[t30] < 1.2 * syy[t5] and syy.max() < 0.01 and sth.max() < 0.01
    assert sxx[t30] > 20.0 * syy[t30]
    # The information of one scan there: nothing along x, much across.
    info = measurement_information(sc.sensors[0], truths[0, 100:101], sc.world.beacon_xy, sc.world)[0]
    assert abs(info[0, 0]) < 1e-9 * info[1, 1] and info[1, 1] > 1e4


@pytest.mark.parametrize("name, duration", [("office", 20.0), ("corridor", 30.0)])
def test_the_bound_is_finite_and_below_mcl_in_the_map_worlds(name, duration):
    """Seeded runs: the evaluation reports a finite bound in a map world (its curve at every
    step too), and mcl's RMSE over the steps the bound is compared on is above it."""
    sc = load_scenario(name)
    runs = run_monte_carlo(sc, ["mcl"], 2, seed=5, duration=duration, jobs=1, progress=False)
    meta, curves = evaluate(sc, runs)
    b = meta["pcrb"]["pos_rmse_m"]
    assert b is not None and math.isfinite(b) and 0.0 < b < 0.05
    assert math.isfinite(meta["pcrb"]["heading_rmse_rad"])
    assert np.all(np.isfinite(curves["pcrb_pos_t"])) and np.all(curves["pcrb_pos_t"] > 0)
    row = meta["filters"]["mcl"]
    assert row["rmse_over_pcrb"] is not None and row["rmse_over_pcrb"] > 1.0
    assert row["pos_rmse_modelled_m"] >= b
