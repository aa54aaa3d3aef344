"""Ray casting on occupancy grids against hand-computed distances and a fine ray march."""

from __future__ import annotations

import math

import numpy as np
import pytest

from beacon_sim.core.occupancy import FREE, OCCUPIED, UNKNOWN, OccupancyGrid, from_walls
from beacon_sim.core.raycast import beam_angles, cast_rays, expected_ranges, scan, unknown_blocks
from beacon_sim.errors import UsageError


def box(n: int = 100, res: float = 0.1) -> np.ndarray:
    """n x n cells with a one-cell wall all round (inner faces at res and (n - 1) res)."""
    cells = np.zeros((n, n), dtype=np.int8)
    cells[0, :] = cells[-1, :] = cells[:, 0] = cells[:, -1] = OCCUPIED
    return cells


def test_axis_aligned_walls_of_a_box():
    g = OccupancyGrid(box(), 0.1)
    r = cast_rays(g, (2.35, 7.2), [0.0, math.pi / 2, -math.pi, -math.pi / 2], 50.0)
    # Inner faces at x = 0.1, x = 9.9, y = 0.1, y = 9.9.
    np.testing.assert_allclose(r, [9.9 - 2.35, 9.9 - 7.2, 2.35 - 0.1, 7.2 - 0.1], atol=1e-12)


def test_a_diagonal_ray_meets_the_nearer_face():
    g = OccupancyGrid(box(), 0.1)
    r = cast_rays(g, (2.35, 2.25), [math.pi / 4], 50.0)
    # Along y - 2.25 = x - 2.35 the face x = 9.9 comes first (7.55 in x, y = 9.8 < 9.9).
    assert r[0] == pytest.approx(7.55 * math.sqrt(2), abs=1e-12)


def test_a_diagonal_wall_from_walls():
    # The wall y = x drawn as a segment through cell corners occupies the diagonal cells and,
    # at each corner, the two cells beside it: no gap for a ray through a corner.
    g = from_walls((0, 0, 10, 10), 0.1, segments=[[(0, 0), (10, 10)]])
    assert g.occupied[50, 49:52].all() and not g.occupied[50, 52] and not g.occupied[50, 48]
    r = cast_rays(g, (9.0, 5.05), [math.pi], 50.0)  # leftwards in row 50: meets x = 5.2
    assert r[0] == pytest.approx(3.8, abs=1e-12)
    # A ray at exactly 45 degrees through the corners of a wall at right angles to it is
    # stopped (with diagonal cells only it would pass every corner between two of them).
    g2 = from_walls((0, 0, 10, 10), 0.1, segments=[[(0, 10), (10, 0)]])
    r = cast_rays(g2, (2.0, 2.0), [math.pi / 4], 50.0)[0]
    assert 3 * math.sqrt(2) - 0.2 * math.sqrt(2) <= r <= 3 * math.sqrt(2) + 1e-12


def test_a_slanted_wall_converges_to_the_true_distance():
    # Wall x + y = 10 on a 1 cm grid; from (2, 2) at 45 degrees the true distance is 3 sqrt 2.
    res = 0.01
    g = from_walls((0, 0, 10, 10), res, segments=[[(0, 10), (10, 0)]])
    r = cast_rays(g, (2.0, 2.0), [math.pi / 4], 50.0)[0]
    true = 3 * math.sqrt(2)
    assert true - 2 * res * math.sqrt(2) <= r <= true + 1e-12


def test_grazing_along_a_grid_line():
    # A resolution of 0.5 m keeps world grid lines exact in binary (0.1 m would round 3.0 m to
    # 29.999... cells).
    cells = box(20, 0.5)
    cells[6, 12:16] = OCCUPIED      # a wall occupying y in [3.0, 3.5), x in [6.0, 8.0)
    g = OccupancyGrid(cells, 0.5)
    # y = 3.0 exactly lies in row 6 (cells are half-open): the ray meets the wall's end face.
    assert cast_rays(g, (1.0, 3.0), [0.0], 50.0)[0] == 5.0
    cells2 = box(20, 0.5)
    cells2[5, 12:16] = OCCUPIED     # the wall now below the line y = 3.0: the ray grazes its top
    g2 = OccupancyGrid(cells2, 0.5)
    assert cast_rays(g2, (1.0, 3.0), [0.0], 50.0)[0] == 8.5   # on to the box's face x = 9.5
    # Just below the line the ray is in row 5 and hits.
    assert cast_rays(g2, (1.0, 2.9999), [0.0], 50.0)[0] == pytest.approx(5.0, abs=1e-12)
    # Moving down along x = 6.0 exactly (column 12): the wall in row 5 is met at its top.
    assert cast_rays(g2, (6.0, 5.0), [-math.pi / 2], 50.0)[0] == pytest.approx(2.0, abs=1e-12)
    # Moving left along y = 3.0 from the right: the end face x = 8.0 of the row-6 wall.
    assert cast_rays(g, (9.0, 3.0), [-math.pi], 50.0)[0] == pytest.approx(1.0, abs=1e-12)


def test_a_ray_through_a_corner_passes_between_diagonal_neighbours():
    cells = np.zeros((10, 10), dtype=np.int8)
    cells[4, 5] = cells[5, 4] = OCCUPIED   # touch only at the corner (5, 5) [cells]
    g = OccupancyGrid(cells, 1.0)
    r = cast_rays(g, (2.5, 2.5), [math.pi / 4], 20.0)[0]
    assert r == 20.0  # through the corner, then off the grid
    cells[5, 5] = OCCUPIED                 # the cell beyond the corner stops it there
    r = cast_rays(OccupancyGrid(cells, 1.0), (2.5, 2.5), [math.pi / 4], 20.0)[0]
    assert r == pytest.approx(2.5 * math.sqrt(2), abs=1e-12)


def test_a_ray_from_inside_an_obstacle_has_range_zero():
    g = OccupancyGrid(box(), 0.1)
    assert np.all(cast_rays(g, (0.05, 5.0), [0.0, 1.0, math.pi], 5.0) == 0.0)


def test_max_range_and_leaving_the_grid():
    g = OccupancyGrid(box(), 0.1)
    assert cast_rays(g, (2.0, 5.0), [0.0], 3.0)[0] == 3.0         # the wall is 7.9 m away
    cells = np.zeros((20, 20), dtype=np.int8)                     # no walls: leaves the grid
    assert cast_rays(OccupancyGrid(cells, 0.1), (1.0, 1.0), [0.3], 7.0)[0] == 7.0
    # A hit exactly at max range counts as the range, beyond it is max range.
    assert cast_rays(g, (2.0, 5.0), [0.0], 7.9)[0] == pytest.approx(7.9)


def test_a_ray_from_outside_the_grid_enters_it():
    g = OccupancyGrid(box(), 0.1)
    assert cast_rays(g, (-3.0, 5.05), [0.0], 50.0)[0] == pytest.approx(3.0, abs=1e-12)
    assert cast_rays(g, (-3.0, 5.05), [math.pi], 50.0)[0] == 50.0
    assert cast_rays(g, (-3.0, 5.05), [0.0], 2.0)[0] == 2.0


def test_unknown_cells_block_only_when_asked():
    cells = box()
    cells[:, 50] = UNKNOWN
    g = OccupancyGrid(cells, 0.1)
    assert cast_rays(g, (2.0, 5.0), [0.0], 50.0)[0] == pytest.approx(7.9)
    assert cast_rays(g, (2.0, 5.0), [0.0], 50.0, blocking=unknown_blocks(g))[0] == pytest.approx(3.0)


def test_the_grid_origin_and_yaw_are_honoured():
    # The box rotated by 90 degrees and moved: its cell (0, 0) corner sits at (5, -2).
    g = OccupancyGrid(box(), 0.1, (5.0, -2.0, math.pi / 2))
    # In the grid frame the point (u, v) = (30, 40) [cells] is world (5 - 4.0, -2 + 3.0).
    xy = g.grid_to_world([30.0, 40.0])
    np.testing.assert_allclose(xy, [1.0, 1.0], atol=1e-12)
    # World +y is the grid's +u: the face u = 99 is 6.9 m away; world -x is +v: 5.9 m.
    r = cast_rays(g, xy, [math.pi / 2, math.pi], 50.0)
    np.testing.assert_allclose(r, [6.9, 5.9], atol=1e-9)


def march(occ: np.ndarray, u0, v0, a, t_max, step):
    """The first sample along the ray (every ``step`` cells) inside an occupied cell."""
    t = np.arange(0.0, t_max, step)
    u = u0 + t * math.cos(a)
    v = v0 + t * math.sin(a)
    c = np.floor(u).astype(int)
    r = np.floor(v).astype(int)
    ok = (c >= 0) & (c < occ.shape[1]) & (r >= 0) & (r < occ.shape[0])
    hit = np.zeros(t.size, dtype=bool)
    hit[ok] = occ[r[ok], c[ok]]
    return t[hit.argmax()] if hit.any() else t_max


def test_random_grids_against_a_fine_ray_march():
    rng = np.random.default_rng(7)
    step = 1e-3
    agree, n = 0, 0
    for _ in range(4):
        occ = rng.random((17, 23)) < 0.12
        g = OccupancyGrid(np.where(occ, OCCUPIED, FREE), 1.0, (0.0, 0.0, 0.0))
        origins = rng.uniform([0, 0], [23, 17], size=(40, 2))
        angles = rng.uniform(-math.pi, math.pi, 40)
        got = cast_rays(g, origins, angles, 30.0)
        for (u, v), a, r in zip(origins, angles, got, strict=True):
            ref = march(occ, u, v, a, 30.0, step)
            assert r <= ref + 1e-9          # the march can only find a hit later, never sooner
            agree += abs(r - ref) <= step + 1e-9
            n += 1
    assert agree >= 0.98 * n


def test_beam_angles():
    a = beam_angles(5, math.pi)
    np.testing.assert_allclose(a, [-math.pi / 2, -math.pi / 4, 0, math.pi / 4, math.pi / 2])
    full = beam_angles(4, 2 * math.pi)
    np.testing.assert_allclose(full, [-math.pi, -math.pi / 2, 0, math.pi / 2])
    assert np.all(full >= -math.pi) and np.all(full < math.pi)
    assert beam_angles(1, 1.0).tolist() == [0.0]
    with pytest.raises(UsageError):
        beam_angles(0, 1.0)


def test_scan_and_expected_ranges_agree():
    g = OccupancyGrid(box(), 0.1)
    rel, r = scan(g, (5.0, 5.0, 0.0), 4, 2 * math.pi, 20.0)
    np.testing.assert_allclose(r, [4.9, 4.9, 4.9, 4.9], atol=1e-12)
    poses = np.array([[5.0, 5.0, 0.0], [2.0, 3.0, 1.0], [8.0, 1.5, -2.5]])
    rel = beam_angles(30, 3.0)
    many = expected_ranges(g, poses, rel, 20.0)
    assert many.shape == (3, 30)
    for p, row in zip(poses, many, strict=True):
        np.testing.assert_array_equal(row, cast_rays(g, p[:2], p[2] + rel, 20.0))


def test_many_rays_in_chunks_match_one_pose_at_a_time():
    g = OccupancyGrid(box(), 0.1)
    cells = box()
    cells[40:45, 20:70] = OCCUPIED
    g = OccupancyGrid(cells, 0.1)
    rng = np.random.default_rng(2)
    poses = np.column_stack([rng.uniform(0.5, 9.5, 50), rng.uniform(0.5, 9.5, 50),
                             rng.uniform(-math.pi, math.pi, 50)])
    rel = beam_angles(30, 2 * math.pi)
    many = expected_ranges(g, poses, rel, 20.0)     # 1500 rays: more than one chunk
    for p, row in zip(poses, many, strict=True):
        np.testing.assert_array_equal(row, cast_rays(g, p[:2], p[2] + rel, 20.0))


def test_bad_max_range():
    with pytest.raises(UsageError, match="max_range"):
        cast_rays(OccupancyGrid(box(), 0.1), (1, 1), [0.0], 0.0)
