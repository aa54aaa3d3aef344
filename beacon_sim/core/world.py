"""The world: a rectangular area [m], the beacons in it and, optionally, walls (an occupancy
grid, docs/maps.md): the robot cannot enter a cell nearer an occupied one than its radius."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property
from types import MappingProxyType

import numpy as np

from beacon_sim.core.beam_model import distance_transform
from beacon_sim.core.occupancy import OccupancyGrid
from beacon_sim.core.types import Beacon, read_only

#: Clearances are exact up to this distance [m] (larger ones read as it): robot radii and
#: kidnap margins are far below it.
CLEARANCE_CAP = 5.0

#: Tries of rejection sampling for a free random pose in a world with walls.
_FREE_POSE_TRIES = 10_000


@dataclass(frozen=True)
class World:
    """Bounds ``(xmin, ymin, xmax, ymax)`` [m], beacons with unique IDs and optional walls
    (``grid``, an occupancy grid; None: an empty room)."""

    bounds: tuple[float, float, float, float]
    beacons: tuple[Beacon, ...]
    grid: OccupancyGrid | None = None

    @cached_property
    def beacon_xy(self) -> np.ndarray:
        """Beacon positions, shape (n, 2) [m], in the order of ``beacons``."""
        xy = np.array([[b.x, b.y] for b in self.beacons], dtype=float)
        return read_only(xy.reshape(-1, 2))  # shared with every filter: nobody may move a beacon

    @cached_property
    def beacon_ids(self) -> np.ndarray:
        """Beacon IDs, shape (n,), in the order of ``beacons``."""
        return read_only(np.array([b.id for b in self.beacons], dtype=int))

    def __getstate__(self) -> dict:
        """Pickled without the cached properties (rebuilt on use; a mappingproxy does not
        pickle), so a scenario that has run still pickles."""
        return {k: v for k, v in self.__dict__.items() if k in self.__dataclass_fields__}

    @cached_property
    def _index_of_id(self) -> Mapping[int, int]:
        return MappingProxyType({b.id: i for i, b in enumerate(self.beacons)})

    def beacon_index(self, ids) -> np.ndarray:
        """Row indices into ``beacon_xy`` for an array of beacon IDs."""
        return np.array([self._index_of_id[int(i)] for i in np.ravel(ids)], dtype=int)

    def beacon_positions(self, ids) -> np.ndarray:
        """Positions, shape (m, 2) [m], of the beacons with the given IDs."""
        return self.beacon_xy[self.beacon_index(ids)]

    @property
    def width(self) -> float:
        return self.bounds[2] - self.bounds[0]

    @property
    def height(self) -> float:
        return self.bounds[3] - self.bounds[1]

    def contains(self, xy) -> np.ndarray | bool:
        """Whether points (shape (2,) or (N, 2)) lie inside the bounds."""
        xy = np.asarray(xy, dtype=float)
        xmin, ymin, xmax, ymax = self.bounds
        inside = (xy[..., 0] >= xmin) & (xy[..., 0] <= xmax)
        inside &= (xy[..., 1] >= ymin) & (xy[..., 1] <= ymax)
        return inside

    def clip(self, pose: np.ndarray) -> np.ndarray:
        """The pose with its position clipped into the bounds (the walls stop the robot)."""
        xmin, ymin, xmax, ymax = self.bounds
        out = np.array(pose, dtype=float)
        out[0] = min(max(out[0], xmin), xmax)
        out[1] = min(max(out[1], ymin), ymax)
        return out

    def random_pose(self, rng: np.random.Generator, margin: float = 0.0) -> np.ndarray:
        """A pose drawn uniformly in the bounds (shrunk by ``margin`` [m]) and all headings;
        in a world with walls, redrawn until it is at least ``margin`` from every wall."""
        xmin, ymin, xmax, ymax = self.bounds
        for _ in range(_FREE_POSE_TRIES if self.grid is not None else 1):
            x = rng.uniform(xmin + margin, xmax - margin)
            y = rng.uniform(ymin + margin, ymax - margin)
            theta = rng.uniform(-np.pi, np.pi)
            if self.grid is None or self.is_free((x, y), margin):
                break
        return np.array([x, y, theta])

    @cached_property
    def clearance(self) -> np.ndarray | None:
        """Distance [m] from each grid cell's centre to the nearest occupied cell's centre,
        shape grid.shape (0 in occupied cells; None without walls)."""
        if self.grid is None:
            return None
        cap = CLEARANCE_CAP / self.grid.resolution  # bounds the transform's passes on open maps
        return read_only(distance_transform(self.grid.occupied, cap) * self.grid.resolution)

    def is_free(self, xy, radius: float = 0.0) -> bool:
        """Whether a disc of ``radius`` [m] centred at ``xy`` (2,) [m] is clear of the walls,
        to a cell's precision: its cell is free and its clearance is at least ``radius``.
        Outside the grid counts as free (the bounds stop the robot there)."""
        if self.grid is None:
            return True
        rc = self.grid.world_to_cell(np.asarray(xy, dtype=float)[:2])
        if not self.grid.in_grid(rc):
            return True
        assert self.clearance is not None
        d = float(self.clearance[int(rc[0]), int(rc[1])])
        return d > 0.0 and d >= min(radius, CLEARANCE_CAP)
