"""How a scan's expected ranges move with the pose: the Jacobian of each beam's ray-cast
range r(x, y, theta) [m] (docs/maps.md, "The bound"), for the PCRB of a range finder.

A beam from the sensor at p = (x, y) along the world heading phi = theta + alpha, unit
direction u = (cos phi, sin phi), hits the wall at q = p + r u. Near q the wall is a line
``n . q = c`` with unit normal n facing the sensor (n . u < 0), so ``r = (c - n . p) / (n . u)``
and, with u_perp = (-sin phi, cos phi)::

    dr/dp     = -n / (n . u)
    dr/dtheta = -r (n . u_perp) / (n . u)

On a grid the wall is a staircase of cell faces, whose normals are the grid axes: the ray
cast's own derivative jumps from one face to the next every cell (a sawtooth), and a beam
is as likely to enter through a face that it meets at 90 degrees as through one it meets
head on. The bound takes the wall's orientation instead, at the scale of a few cells: n is
the normal of a weighted least-squares line through the wall's surface cells (occupied
cells with a free 4-neighbour) within 6 cells of the cell the beam enters
(:func:`wall_normals`, Gaussian weights, sigma 3 cells). It is exact for walls along the
grid's axes and at 45 degrees (by symmetry) and within a degree or two at other angles.
The tests hold it to least-squares slopes of the ray cast itself over offsets of a few
cells (tests/evaluation/test_scan_pcrb.py): exact for axis-aligned walls, 2 % at 45 degrees, 4 % at
30 degrees. Where the surface cells around the hit are no line (a corner, a pillar or a
door jamb smaller than the window: the fit's smaller spread over a tenth of the larger,
``MAX_CORNERNESS``) the normal is that of the cell face the beam enters through, a grid
axis: the ray cast's own derivative there (exact for axis-aligned pillars and corners).

Beams that carry no position information under the hit model are *dropped* (``usable`` is
False, their rows zero): no wall within ``max_range`` (or the ray left the grid), a ray that
starts inside a wall (r = 0), grazing hits, whose incidence (the angle between -u and n) is
over ``max_incidence`` (default 75 degrees: there r jumps as the beam slides along the wall
and the linearisation means nothing). At an edge r is discontinuous (a beam just past a
door jamb reads the wall behind it): the derivative is the one of the face that was hit.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from beacon_sim.core.occupancy import OccupancyGrid
from beacon_sim.core.raycast import expected_ranges
from beacon_sim.core.types import read_only

#: Beams hitting a wall more obliquely than this [rad] are dropped (75 degrees).
MAX_INCIDENCE = math.radians(75.0)
#: The wall's line is fitted to the wall's surface cells within this radius [cells] of the
#: hit cell, Gaussian-weighted with this sigma [cells].
_NORMAL_RADIUS = 6
_NORMAL_SIGMA = 3.0
#: A fit whose smaller spread is more than this share of the larger is no line (a corner,
#: a pillar's end): its beams take the normal of the cell face they enter through.
MAX_CORNERNESS = 0.1


@lru_cache(maxsize=8)
def _surface(grid: OccupancyGrid) -> np.ndarray:
    """The occupied cells with a free 4-neighbour (a wall's surface), padded by
    ``_NORMAL_RADIUS`` cells of False on every side; off the grid counts as occupied."""
    occ = grid.occupied
    rows, cols = occ.shape
    big = np.ones((rows + 2, cols + 2), dtype=bool)
    big[1:-1, 1:-1] = occ
    free_nb = ~big[:-2, 1:-1] | ~big[2:, 1:-1] | ~big[1:-1, :-2] | ~big[1:-1, 2:]
    k = _NORMAL_RADIUS
    out = np.zeros((rows + 2 * k, cols + 2 * k), dtype=bool)
    out[k:-k, k:-k] = occ & free_nb
    return read_only(out)


def _window() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    k = _NORMAL_RADIUS
    di, dj = np.mgrid[-k:k + 1, -k:k + 1]
    keep = di * di + dj * dj <= k * k
    di, dj = di[keep].astype(float), dj[keep].astype(float)
    return di, dj, np.exp(-0.5 * (di * di + dj * dj) / _NORMAL_SIGMA**2)


_DI, _DJ, _W = _window()


def wall_normals(grid: OccupancyGrid, cells) -> tuple[np.ndarray, np.ndarray]:
    """The wall's unit normal (du, dv) in grid axes at hit cells ``cells`` (..., 2) as
    (row, col), sign undetermined, and whether the surface there is a line.

    A weighted least-squares line through the surface cells' centres (occupied cells with a
    free 4-neighbour) within ``_NORMAL_RADIUS`` cells: the normal is the direction of their
    smaller spread. Exact for walls along the grid's axes and at 45 degrees (by symmetry);
    a staircase at other angles is fitted to about a degree."""
    cells = np.asarray(cells, dtype=np.int64)
    shape = cells.shape[:-1]
    rc = cells.reshape(-1, 2)
    surf = _surface(grid)
    k = _NORMAL_RADIUS
    rows, cols = grid.shape
    r = np.clip(rc[:, 0], 0, rows - 1)[:, None] + k + _DI.astype(np.int64)[None]
    c = np.clip(rc[:, 1], 0, cols - 1)[:, None] + k + _DJ.astype(np.int64)[None]
    w = surf[r, c] * _W[None]                                  # (N, M)
    s0 = np.maximum(w.sum(axis=1), 1e-300)
    mu = (w @ _DJ) / s0, (w @ _DI) / s0                         # centroid (du, dv)
    cuu = (w @ (_DJ * _DJ)) / s0 - mu[0] ** 2
    cvv = (w @ (_DI * _DI)) / s0 - mu[1] ** 2
    cuv = (w @ (_DI * _DJ)) / s0 - mu[0] * mu[1]
    along = 0.5 * np.arctan2(2.0 * cuv, cuu - cvv)             # the line's direction
    half_tr = 0.5 * (cuu + cvv)
    rad = np.hypot(0.5 * (cuu - cvv), cuv)
    lam_big, lam_small = half_tr + rad, half_tr - rad
    line = (lam_big > 0) & (lam_small <= MAX_CORNERNESS * lam_big)
    n = np.stack([-np.sin(along), np.cos(along)], axis=-1)
    return n.reshape(*shape, 2), line.reshape(shape)


def scan_jacobian(grid: OccupancyGrid, poses, rel_angles, max_range: float, *,
                  max_incidence: float = MAX_INCIDENCE) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Expected ranges and their derivatives for scans from many poses.

    Parameters
    ----------
    grid : OccupancyGrid
    poses : array_like (R, 3) [m, m, rad]
        Sensor poses (the sensor at the robot's centre), world frame.
    rel_angles : array_like (B,) [rad]
        Beam angles relative to the heading.
    max_range : float
        The sensor's maximum range [m].
    max_incidence : float
        Beams hitting more obliquely than this [rad] are dropped.

    Returns
    -------
    ranges : ndarray (R, B) [m]
        The ray-cast ranges.
    jac : ndarray (R, B, 3)
        ``dr / d(x, y, theta)`` [m/m, m/m, m/rad]; zero rows where not usable.
    usable : bool ndarray (R, B)
        Beams that hit a wall within range at an incidence up to ``max_incidence``.
    """
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    rel = np.asarray(rel_angles, dtype=float).ravel()
    ranges = expected_ranges(grid, poses, rel, max_range)
    phi = poses[:, 2:3] + rel[None, :]
    u = np.stack([np.cos(phi), np.sin(phi)], axis=-1)  # (R, B, 2), world frame
    # The occupied cell the beam enters: a quarter of a cell beyond the hit point.
    rc = grid.world_to_cell(poses[:, None, :2] + (ranges + 0.25 * grid.resolution)[..., None] * u)
    inside = grid.in_grid(rc)
    n_fit, line = wall_normals(grid, rc)
    # No line there (a corner, a pillar smaller than the fit's window): the normal of the
    # cell face the beam enters through, the grid line its hit point lies on.
    hit = grid.world_to_grid(poses[:, None, :2] + ranges[..., None] * u)
    off = np.abs(hit - np.round(hit))                     # (R, B, 2): distance to a line
    on_vertical = (off[..., 0] <= off[..., 1])[..., None]
    face = np.where(on_vertical, np.array([1.0, 0.0]), np.array([0.0, 1.0]))
    n_grid = np.where(line[..., None], n_fit, face)
    c, s = math.cos(grid.origin[2]), math.sin(grid.origin[2])  # grid axes -> world
    n = np.stack([c * n_grid[..., 0] - s * n_grid[..., 1],
                  s * n_grid[..., 0] + c * n_grid[..., 1]], axis=-1)
    n *= np.where(np.sum(n * u, axis=-1) > 0, -1.0, 1.0)[..., None]  # facing the sensor
    nu = np.sum(n * u, axis=-1)
    usable = inside & (ranges > 0.0) & (ranges < max_range) & (nu <= -math.cos(max_incidence))
    jac = np.zeros((*ranges.shape, 3))
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = np.where(usable, -1.0 / nu, 0.0)
    u_perp_n = -u[..., 1] * n[..., 0] + u[..., 0] * n[..., 1]
    jac[..., 0] = inv * n[..., 0]
    jac[..., 1] = inv * n[..., 1]
    jac[..., 2] = inv * ranges * u_perp_n
    return ranges, jac, usable


def scan_information(grid: OccupancyGrid | None, poses, rel_angles, max_range: float,
                     sigma_hit: float, hit_weight: float = 1.0) -> np.ndarray:
    """Fisher information (R, 3, 3) of one scan from each of ``poses`` (R, 3) under the beam
    model's hit part: ``hit_weight * sum over usable beams of J^T J / sigma_hit^2``.
    ``hit_weight`` is z_hit (of the weights divided by their sum): the information of a
    mixture is at most the weighted information of its parts (convexity), and the short,
    max and random parts carry none to first order, so this over-states the scan's
    information and the bound stays a lower bound. A world without walls gives zero."""
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    if grid is None:
        return np.zeros((poses.shape[0], 3, 3))
    _, jac, _ = scan_jacobian(grid, poses, rel_angles, max_range)
    return (hit_weight / sigma_hit**2) * np.einsum("rbi,rbj->rij", jac, jac)
