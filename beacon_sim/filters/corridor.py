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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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
