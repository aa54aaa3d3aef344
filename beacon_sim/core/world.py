"""The world: a rectangular area [m] and the beacons in it."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property
from types import MappingProxyType

import numpy as np

from beacon_sim.core.types import Beacon, read_only


@dataclass(frozen=True)
class World:
    """Bounds ``(xmin, ymin, xmax, ymax)`` [m] and beacons with unique IDs."""

    bounds: tuple[float, float, float, float]
    beacons: tuple[Beacon, ...]

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
        """A pose drawn uniformly in the bounds (shrunk by ``margin`` [m]) and all headings."""
        xmin, ymin, xmax, ymax = self.bounds
        x = rng.uniform(xmin + margin, xmax - margin)
        y = rng.uniform(ymin + margin, ymax - margin)
        theta = rng.uniform(-np.pi, np.pi)
        return np.array([x, y, theta])
