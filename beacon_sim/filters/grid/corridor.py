"""Seed 004's corridor: the discrete Bayes filter in its smallest form.

A corridor of ``n_cells`` cells, traversed in either direction: state ``i < n`` is cell ``i``
facing +x, state ``2n - 1 - i`` is cell ``i`` facing -x (so a 180 degree turn maps state
``i`` to ``2n - 1 - i``, as the seed's turn formula). Some cells have a door in the north
or south wall; at the ends there is a wall in front. The robot senses walls left / right /
front, and the reading either matches a state's layout (factor 0.6) or not (factor 0.2).

Control updates (seed 004, section 3.1):

- forward: ``bel(x_i) = 0.8 p(x_{i-1}) + 0.1 p(x_{i-2}) + 0.1 p(x_i)`` within each direction,
  mass that would leave the corridor is lost, then the belief is normalised;
- turn: ``bel(x_i) = 0.9 p(x_{N-1-i}) + 0.1 p(x_i)`` with N = 2n states.

Measurement update (section 3.2): ``bel(x) = eta p(z | x) bel(x)``.

``CorridorFilter`` (``--filter corridor``) runs it on the ``corridor`` scenario: the
robot's driving cut into the seed's "forward one cell" and "turn" commands, the walls read
from its laser scan.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from beacon_sim.core.sensor_kinds import is_scan
from beacon_sim.core.types import Control, Measurement
from beacon_sim.filters.base import FilterBase, FilterContext, FilterError, GaussianBelief, GridBelief


@dataclass(frozen=True)
class Corridor:
    """A corridor with doors. Layout strings name the walls sensed: ``L``, ``R``, ``F``."""

    n_cells: int = 10
    north_doors: tuple[int, ...] = (2, 6)
    south_doors: tuple[int, ...] = (4,)
    p_move: tuple[float, float, float] = (0.8, 0.1, 0.1)   # one cell, two cells, stay
    p_turn: float = 0.9
    p_hit: float = 0.6
    p_miss: float = 0.2

    @property
    def n_states(self) -> int:
        return 2 * self.n_cells

    def cell_and_heading(self, state: int) -> tuple[int, int]:
        """Cell index and direction (+1 facing +x, -1 facing -x) of a state."""
        n = self.n_cells
        return (state, 1) if state < n else (2 * n - 1 - state, -1)

    def layout(self, state: int) -> str:
        """Walls a perfect sensor reports in ``state``: e.g. ``"LR"``, ``"R"``, ``"LRF"``."""
        cell, d = self.cell_and_heading(state)
        north_wall = cell not in self.north_doors
        south_wall = cell not in self.south_doors
        left, right = (north_wall, south_wall) if d > 0 else (south_wall, north_wall)
        front = cell == (self.n_cells - 1 if d > 0 else 0)
        return "L" * left + "R" * right + "F" * front

    def uniform(self) -> np.ndarray:
        """The initial belief: 1 / (2 n) in every state."""
        return np.full(self.n_states, 1.0 / self.n_states)

    def forward(self, bel: np.ndarray) -> np.ndarray:
        """Control update for "move forward one cell" (normalised)."""
        n = self.n_cells
        one, two, stay = self.p_move
        out = np.empty_like(bel)
        for half in (slice(0, n), slice(n, 2 * n)):     # the two directions
            p = bel[half]
            q = stay * p
            q[1:] += one * p[:-1]
            q[2:] += two * p[:-2]
            out[half] = q
        return out / out.sum()

    def turn(self, bel: np.ndarray) -> np.ndarray:
        """Control update for a 180 degree turn (already normalised)."""
        return self.p_turn * bel[::-1] + (1.0 - self.p_turn) * bel

    def sense(self, bel: np.ndarray, reading: str) -> np.ndarray:
        """Measurement update with a reading such as ``"LR"`` (order of letters ignored)."""
        want = set(reading)
        match = np.array([set(self.layout(s)) == want for s in range(self.n_states)])
        out = bel * np.where(match, self.p_hit, self.p_miss)
        return out / out.sum()


def walls_seen(m: Measurement, wall_dist: float, half_width: float = math.radians(15)) -> str:
    """The seed's reading from a laser scan: ``L``, ``R``, ``F`` for a wall within
    ``wall_dist`` [m] to the left (+90 deg), right (-90 deg) or front (0 deg), each by the
    median of the beams within ``half_width`` [rad] of that direction (none there: no wall)."""
    ranges, rel = np.asarray(m.z[:, 0]), np.asarray(m.z[:, 1])
    out = ""
    for letter, centre in (("L", math.pi / 2), ("R", -math.pi / 2), ("F", 0.0)):
        d = np.abs(np.angle(np.exp(1j * (rel - centre))))
        near = ranges[d <= half_width]
        if near.size and float(np.median(near)) < wall_dist:
            out += letter
    return out


class CorridorFilter(FilterBase):
    """Seed 004's discrete Bayes filter driven by the corridor scenario.

    The 20 states of :class:`Corridor` (cell and direction). The motion is cut into the
    seed's commands: every ``cell`` metres driven is a "forward", every half turn
    accumulated a "turn" (after a "forward" if more than half a cell was driven since the
    last), each followed by a sensing of the next scan's walls (:func:`walls_seen`).
    The estimate is the belief's mean position on the corridor's centre line and circular
    mean heading (each state's cell centre moved on by the odometry since the last count),
    with the cells' spread (plus a cell's uniform variance) as covariance;
    ``belief()`` is the grid of cells for the window's heat map. Without scans (another
    world) it only moves its belief.
    """

    supports_global = True
    defaults: ClassVar[dict[str, Any]] = {
        "x0": 0.0,            # [m] the corridor's start (cell 0's west side)
        "y_centre": 0.5,      # [m] its centre line
        "width": 1.0,         # [m]
        "cell": 1.0,          # [m] a cell's length
        "wall_dist": 0.8,     # [m] a beam shorter than this is a wall
    }

    def __init__(self, ctx: FilterContext):
        super().__init__(ctx)
        p = self.params
        if not (p["cell"] > 0 and p["width"] > 0 and p["wall_dist"] > 0):
            raise FilterError("corridor: cell, width and wall_dist must be > 0")
        self.corridor = Corridor()
        self.bel = self.corridor.uniform()
        self._driven = 0.0
        self._turned = 0.0
        self._pending_sense = False
        self.last_reading = ""

    def reset(self, initial: GaussianBelief | None) -> None:
        """None: uniform over the 20 states; a Gaussian: its mean's cell and direction."""
        self.bel = self.corridor.uniform()
        if initial is not None:
            self.bel = np.zeros(self.corridor.n_states)
            self.bel[self.state_of(np.asarray(initial.mean, dtype=float))] = 1.0
        self._driven = self._turned = 0.0
        self._pending_sense = True

    def state_of(self, pose: np.ndarray) -> int:
        """The state of a pose [m, m, rad]: its cell (clipped into the corridor), its direction."""
        n = self.corridor.n_cells
        cell = int(np.clip(math.floor((pose[0] - self.params["x0"]) / self.params["cell"]), 0, n - 1))
        return cell if math.cos(pose[2]) >= 0 else 2 * n - 1 - cell

    def predict(self, control: Control, dt: float) -> None:
        """Odometry since the last count: the distance driven along the corridor (the
        command's speed times the cosine of the heading turned since, so that an arc
        through a turn counts what it gains and loses along the corridor) and the angle
        turned; each cell of distance a "forward", each half turn a "turn"."""
        half = 0.5 * control.omega * dt
        self._driven += control.v * dt * math.cos(self._turned + half)
        self._turned += 2 * half
        cell = self.params["cell"]
        while self._driven >= cell:
            self.bel = self.corridor.forward(self.bel)
            self._driven -= cell
            self._pending_sense = True
        while abs(self._turned) >= math.pi * 0.9:      # a half turn (the driver's, give or take)
            if self._driven >= 0.5 * cell:              # past the next cell's boundary first
                self.bel = self.corridor.forward(self.bel)
                self._driven -= cell
            self.bel = self.corridor.turn(self.bel)
            self._turned -= math.copysign(math.pi, self._turned)
            # The robot is _driven past its cell's centre in the old direction: as far
            # behind it in the new one (the next "forward" comes at the next centre, where
            # the sensing sees the doors whole).
            self._driven = -self._driven
            self._pending_sense = True

    def update(self, measurements: Sequence[Measurement]) -> None:
        scans = [m for m in measurements if is_scan(m.kind) and len(m)]
        if scans and self._pending_sense:
            self.last_reading = walls_seen(scans[-1], self.params["wall_dist"])
            self.bel = self.corridor.sense(self.bel, self.last_reading)
            self._pending_sense = False

    def estimate(self) -> tuple[np.ndarray, np.ndarray]:
        p, n = self.params, self.corridor.n_cells
        states = np.arange(self.corridor.n_states)
        cells = np.where(states < n, states, 2 * n - 1 - states)
        # Each state's pose now: its cell's centre (where the last "forward" or "turn" left
        # the robot) moved on by the distance driven and the angle turned since, along the
        # state's direction; the belief changes only every metre, the robot in between.
        east = states < n
        x = p["x0"] + (cells + 0.5) * p["cell"] + np.where(east, 1.0, -1.0) * self._driven
        th = np.angle(np.exp(1j * (np.where(east, 0.0, -math.pi) + self._turned)))
        mx = float(self.bel @ x)
        s, c = float(self.bel @ np.sin(th)), float(self.bel @ np.cos(th))
        mth = math.atan2(s, c) if abs(s) + abs(c) > 1e-12 else 0.0
        mth = -math.pi if mth >= math.pi else mth
        dth = np.angle(np.exp(1j * (th - mth)))
        e = np.stack([x - mx, np.zeros_like(x), dth])
        cov = (e * self.bel) @ e.T
        cov[0, 0] += p["cell"] ** 2 / 12
        cov[1, 1] += p["width"] ** 2 / 12
        cov[2, 2] += 1e-4
        return np.array([mx, p["y_centre"], mth]), 0.5 * (cov + cov.T)

    def belief(self) -> GridBelief:
        n = self.corridor.n_cells
        per_cell = self.bel[:n] + self.bel[::-1][:n]
        p = self.params
        return GridBelief(per_cell[:, None] / per_cell.sum(), (p["x0"], p["y_centre"] - p["width"] / 2),
                          p["cell"])


__all__ = ["Corridor", "CorridorFilter", "walls_seen"]
