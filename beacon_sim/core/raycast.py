"""Ray casting on an occupancy grid, many rays at once (the range finder's expected ranges).

The traversal is Amanatides and Woo's (a grid DDA), vectorised over rays and over the grid
lines each ray crosses: a ray enters a new cell only by crossing a vertical grid line
(u = integer) or a horizontal one (v = integer); the k-th crossing of each kind is at
``t = t0 + k * dt`` with the cell it enters known in closed form. The range is the distance to
the first crossing that enters an occupied cell: exact to the cell boundary, up to rounding.

Conventions (docs/maps.md): cells are half-open ``[col, col+1) x [row, row+1)`` in grid
units, so a ray running exactly along a grid line lies in the cells above (or right of) it.
A ray through a cell corner passes between the two cells that share only that corner. A ray
that starts in an occupied cell has range 0. A ray that meets nothing within ``max_range``
(or leaves the grid) returns ``max_range``. Unknown cells are free (AMCL stops at them:
pass ``blocking=`` to choose).
"""

from __future__ import annotations

import numpy as np

from beacon_sim.core import portable_math as pm
from beacon_sim.core.angles import wrap
from beacon_sim.core.occupancy import UNKNOWN, OccupancyGrid
from beacon_sim.errors import UsageError

#: Crossings examined per round: rays that hit early stop after the first round.
_BLOCK = 64
#: Rays cast together: many rays (particles x beams) go in chunks of this many.
_RAYS_PER_CHUNK = 1024


def cast_rays(grid: OccupancyGrid, origins, angles, max_range: float, *,
              blocking: np.ndarray | None = None) -> np.ndarray:
    """Ranges [m] from world points along world headings to the first occupied cell.

    Parameters
    ----------
    grid : OccupancyGrid
    origins : array_like, shape (n, 2) [m]
        Ray start points in the world frame (or shape (2,), shared by all rays).
    angles : array_like, shape (n,) [rad]
        Ray headings in the world frame, CCW from +x.
    max_range : float
        Longest range [m], > 0.
    blocking : ndarray of bool, shape grid.shape, optional
        Cells that stop a ray; default ``grid.occupied``.

    Returns
    -------
    ranges : ndarray, shape (n,) [m], in [0, max_range]
    """
    if not max_range > 0:
        raise UsageError(f"max_range must be > 0 [m], got {max_range!r}")
    angles = np.atleast_1d(np.asarray(angles, dtype=float))
    origins = np.broadcast_to(np.asarray(origins, dtype=float), (*angles.shape, 2))
    uv = grid.world_to_grid(origins)
    heading = angles - grid.origin[2]  # into the grid's axes
    cells = grid.occupied if blocking is None else np.asarray(blocking, dtype=bool)
    # Snap the rounding of cos/sin at multiples of pi/2 (sin(pi) = 1.2e-16) to zero, so that
    # a ray along a grid line at heading pi behaves as at -pi and at 0.
    cv, cu = pm.sincos(heading)   # portable: rays decide the truth's readings
    cu[np.abs(cu) < 1e-12] = 0.0
    cv[np.abs(cv) < 1e-12] = 0.0
    t_max = max_range / grid.resolution
    n = angles.size
    if n <= _RAYS_PER_CHUNK:
        t = _cast_grid(cells, uv[:, 0], uv[:, 1], cu, cv, t_max)
    else:  # chunks keep the work arrays small (in cache, no page faults on fresh memory)
        t = np.empty(n)
        for a in range(0, n, _RAYS_PER_CHUNK):
            b = min(a + _RAYS_PER_CHUNK, n)
            t[a:b] = _cast_grid(cells, uv[a:b, 0], uv[a:b, 1], cu[a:b], cv[a:b], t_max)
    return np.minimum(t * grid.resolution, max_range)


def line_of_sight(grid: OccupancyGrid, origins, targets) -> np.ndarray:
    """Whether the segment from each origin (n, 2) [m] to its target (n, 2) [m] is clear:
    the first occupied cell it enters is none, or the target's own cell (a beacon on or in
    a wall is seen from the wall's free side). One ray cast per pair, vectorised; a target
    at its origin is seen. Returns bool (n,)."""
    origins = np.asarray(origins, dtype=float).reshape(-1, 2)
    targets = np.asarray(targets, dtype=float).reshape(-1, 2)
    d = targets - origins
    dist = pm.hypot(d[:, 0], d[:, 1])
    if dist.size == 0:
        return np.zeros(0, dtype=bool)
    reach = float(dist.max()) + grid.resolution
    r = cast_rays(grid, origins, pm.atan2(d[:, 1], d[:, 0]), reach)
    clear = r >= dist
    # Where the ray stopped short of the target: is the cell it entered the target's?
    short = np.flatnonzero(~clear)
    if short.size:
        u = d[short] / np.maximum(dist[short], 1e-300)[:, None]
        entered = grid.world_to_cell(origins[short] + (r[short] + 0.25 * grid.resolution)[:, None] * u)
        own = grid.world_to_cell(targets[short])
        clear[short] = np.all(entered == own, axis=1)
    return clear


def unknown_blocks(grid: OccupancyGrid) -> np.ndarray:
    """The blocking mask AMCL uses: occupied and unknown cells stop a ray."""
    return grid.occupied | (grid.cells == UNKNOWN)


def beam_angles(n_beams: int, fov: float) -> np.ndarray:
    """Beam headings [rad] relative to the sensor, shape (n_beams,), wrapped to [-pi, pi).

    ``n_beams`` beams spread evenly over ``fov`` [rad], centred on the heading; end points
    included, except for a full circle (fov >= 2 pi), where they would coincide. One beam
    points straight ahead.
    """
    if n_beams < 1:
        raise UsageError(f"n_beams must be >= 1, got {n_beams!r}")
    if not 0 < fov:
        raise UsageError(f"fov must be > 0 [rad], got {fov!r}")
    if n_beams == 1:
        return np.zeros(1)
    if fov >= 2 * np.pi:
        return wrap(-np.pi + 2 * np.pi * np.arange(n_beams) / n_beams)
    return wrap(np.linspace(-fov / 2, fov / 2, n_beams))


def scan(grid: OccupancyGrid, pose, n_beams: int, fov: float, max_range: float, *,
         blocking: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """One noise-free scan from ``pose`` (x [m], y [m], theta [rad]) with the sensor at the
    robot's centre: (beam angles relative to the robot [rad], ranges [m]), each (n_beams,)."""
    rel = beam_angles(n_beams, fov)
    x, y, theta = (float(v) for v in pose)
    ranges = cast_rays(grid, (x, y), theta + rel, max_range, blocking=blocking)
    return rel, ranges


def expected_ranges(grid: OccupancyGrid, poses, rel_angles, max_range: float, *,
                    blocking: np.ndarray | None = None) -> np.ndarray:
    """Noise-free ranges [m], shape (n_poses, n_beams), for many poses (e.g. particles)
    of shape (n_poses, 3) and beam angles relative to the robot, shape (n_beams,)."""
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    rel = np.asarray(rel_angles, dtype=float).ravel()
    n, b = len(poses), len(rel)
    origins = np.repeat(poses[:, :2], b, axis=0)
    angles = (poses[:, 2:3] + rel[None, :]).ravel()
    return cast_rays(grid, origins, angles, max_range, blocking=blocking).reshape(n, b)


def _cast_grid(occ: np.ndarray, u0: np.ndarray, v0: np.ndarray, cu: np.ndarray, cv: np.ndarray,
               t_max: float) -> np.ndarray:
    """Distance [cells] along unit directions (cu, cv) from (u0, v0) [cells] to the first
    cell of ``occ`` (rows, cols) a ray enters; ``inf`` when none is met within ``t_max``."""
    rows, cols = occ.shape
    n = u0.shape[0]
    out = np.full(n, np.inf)
    # Rays that start outside the grid are moved to where they enter it (slab method).
    with np.errstate(divide="ignore", invalid="ignore"):
        ta = np.where(cu != 0, (0.0 - u0) / cu, np.where((u0 >= 0) & (u0 < cols), -np.inf, np.inf))
        tb = np.where(cu != 0, (cols - u0) / cu, np.where((u0 >= 0) & (u0 < cols), np.inf, -np.inf))
        tc = np.where(cv != 0, (0.0 - v0) / cv, np.where((v0 >= 0) & (v0 < rows), -np.inf, np.inf))
        td = np.where(cv != 0, (rows - v0) / cv, np.where((v0 >= 0) & (v0 < rows), np.inf, -np.inf))
    t_in = np.maximum(np.maximum(np.minimum(ta, tb), np.minimum(tc, td)), 0.0)
    t_out = np.minimum(np.maximum(ta, tb), np.maximum(tc, td))
    meets = (t_in < t_out) & (t_in <= t_max)
    u0 = np.where(t_in > 0, u0 + t_in * cu, u0)
    v0 = np.where(t_in > 0, v0 + t_in * cv, v0)
    i0 = np.clip(np.floor(u0), 0, cols - 1).astype(np.int64)
    j0 = np.clip(np.floor(v0), 0, rows - 1).astype(np.int64)
    # The grid with a border of blocking cells: a ray that leaves it "hits" the border at
    # t_out (then reported as no hit), so no crossing needs a bounds check before that, and
    # the ones after it do not matter (only the first hit counts).
    w2 = cols + 2
    padded = np.ones((rows + 2, w2), dtype=bool)
    padded[1:-1, 1:-1] = occ
    flat = padded.ravel()
    start_hit = meets & flat[(j0 + 1) * w2 + i0 + 1]
    out[start_hit] = t_in[start_hit]
    active = np.flatnonzero(meets & ~start_hit)
    if active.size == 0:
        return out
    u0, v0, cu, cv, i0, j0 = u0[active], v0[active], cu[active], cv[active], i0[active], j0[active]
    t_in, t_out = t_in[active], t_out[active]
    m = active.size
    with np.errstate(divide="ignore", invalid="ignore"):
        # Per axis: distance to the first grid line, distance between lines.
        tu0 = np.where(cu != 0, (i0 + (cu > 0) - u0) / cu, np.inf)
        tv0 = np.where(cv != 0, (j0 + (cv > 0) - v0) / cv, np.inf)
        du = np.where(cu != 0, 1.0 / np.abs(cu), 0.0)
        dv = np.where(cv != 0, 1.0 / np.abs(cv), 0.0)
    su = np.where(cu > 0, 1, -1)
    sv = np.where(cv > 0, 1, -1)
    # The k-th crossing (k = 0, 1, ...) of a vertical line enters column i0 + su (k + 1), at
    # the row the ray is in there: floor(v) moving up, ceil(v) - 1 moving down (a ray moving
    # down onto a line is below it). With s = sv: row = s floor(s v) - (s < 0). The padded
    # flat index (row + 1) w2 + col + 1 is then floor(q) A + B + C k, q = s v.
    axes = []
    for t0, dt, i_s, s_mine, _j_s, c_other, p0_other, along_u in (
            (tu0, du, i0, su, j0, cv, v0, True), (tv0, dv, j0, sv, i0, cu, u0, False)):
        s = np.where(c_other >= 0, 1, -1)  # not moving along the other axis: floor
        neg = (s < 0).astype(np.int64)
        if along_u:   # mine = column, other = row
            a_coef = s * w2
            b_coef = (1 - neg) * w2 + i_s + s_mine + 1
            c_coef = s_mine
        else:         # mine = row, other = column
            a_coef = s
            b_coef = (i_s + s_mine + 1) * w2 + 1 - neg
            c_coef = s_mine * w2
        axes.append((t0, dt, s * p0_other, np.abs(c_other), a_coef.astype(float),
                     b_coef.astype(float), c_coef.astype(float)))
    k_limit = int(min(np.ceil(t_max) + 2, max(rows, cols) + 3))
    best = np.full(m, np.inf)
    rest = np.arange(m)
    k0 = 0
    t_left = t_max - t_in  # the range still to cover from the (moved) start [cells]
    while rest.size and k0 < k_limit:
        k = np.arange(k0, min(k0 + _BLOCK, k_limit), dtype=float)
        last = np.full(rest.size, np.inf)
        b = best[rest]
        for t0, dt, q0, c_abs, a_coef, b_coef, c_coef in axes:
            t = t0[rest, None] + k * dt[rest, None]          # (m, K) crossing distances [cells]
            q = q0[rest, None] + t * c_abs[rest, None]
            idx = np.floor(q)
            idx *= a_coef[rest, None]
            idx += b_coef[rest, None] + k * c_coef[rest, None]
            with np.errstate(invalid="ignore"):  # t = inf on an axis the ray never crosses
                hit = flat.take(idx.astype(np.int64), mode="clip")
            first = hit.argmax(axis=1)
            rr = np.arange(rest.size)
            t_hit = np.where(hit[rr, first], t[rr, first], np.inf)
            b = np.minimum(b, t_hit)
            last = np.minimum(last, np.where(dt[rest] > 0, t[:, -1], np.inf))
        best[rest] = b
        done = (b <= last) | (last > t_left[rest])
        rest = rest[~done]
        k0 += _BLOCK
    best += t_in
    # A hit on the border (at t_out) is the ray leaving the grid: no hit.
    best[best >= t_out - 1e-9] = np.inf
    out[active] = best
    return out
