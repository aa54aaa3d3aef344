"""A filter parameter's contract: its default, its documented range and what it means
(``Param``), and the bounds on what a built-in filter may allocate.

A value given to a filter (scenario ``[filters.NAME]``, ``--set``, a recording's
parameters) is checked against its ``Param`` when the filter is built: an integer parameter
takes an integer, a number parameter a finite number inside ``[low, high]`` (inclusive).
Every mistake is a one-line :class:`FilterError` (docs/filters.md, "Parameter ranges").
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, NamedTuple

from beacon_sim.core.world import World
from beacon_sim.filters.base import FilterError

#: Most particles a particle filter may hold (positions and weights: about 50 MB).
MAX_PARTICLES = 1_000_000
#: Most cells (x cells * y cells * heading bins) of a grid, and most (beacon, x-y cell)
#: pairs its precomputed geometry may hold: each array of that size is 160 MB.
MAX_GRID_CELLS = 20_000_000
MAX_GRID_BEACON_CELLS = 20_000_000


class Range(NamedTuple):
    """The documented, inclusive range ``[low, high]`` of a number parameter, and what the
    parameter means (units in the text). A registry record declares one per parameter; the
    default comes from the filter class's ``defaults``."""

    low: float
    high: float
    doc: str = ""


@dataclass(frozen=True)
class Param:
    """One parameter's contract: ``default`` (its type is the parameter's type), the
    inclusive range ``[low, high]`` (None: any finite value), and ``doc``."""

    default: Any
    low: float | None = None
    high: float | None = None
    doc: str = ""

    @classmethod
    def of(cls, default: Any, declared: Range | None) -> Param:
        """The contract of a parameter with ``default`` and a declared range (or none)."""
        return cls(default) if declared is None else cls(default, *declared)

    def check(self, owner: str, key: str, value: Any) -> None:
        """Raise :class:`FilterError` (one line, naming ``owner`` and ``key``) when ``value``
        is not an integer for an integer parameter, not finite for a number parameter, or
        outside ``[low, high]``."""
        default = self.default
        is_number = isinstance(value, int | float) and not isinstance(value, bool)
        if isinstance(default, int) and not isinstance(default, bool) and not isinstance(value, int):
            raise FilterError(f"{owner}: parameter {key} = {value!r}: expected an integer like {default!r}")
        if isinstance(default, float) and is_number:
            try:
                finite = math.isfinite(float(value))
            except OverflowError:
                finite = False
            if not finite:
                raise FilterError(f"{owner}: parameter {key} = {value!r}: expected a finite number")
        if self.low is not None and self.high is not None and is_number \
                and not self.low <= value <= self.high:
            raise FilterError(f"{owner}: parameter {key} = {value!r}: expected a number in "
                              f"[{self.low:g}, {self.high:g}]")


def particle_memory(owner: str, params: Mapping[str, Any], world: World) -> None:
    """Raise :class:`FilterError` when a particle filter would hold more than
    :data:`MAX_PARTICLES` particles (``n_particles`` or ``n_max``)."""
    n = max(int(params.get(k, 0)) for k in ("n_particles", "n_max"))
    if n > MAX_PARTICLES:
        raise FilterError(f"{owner}: {n:,} particles: expected at most {MAX_PARTICLES:,}")


def grid_memory(owner: str, params: Mapping[str, Any], world: World) -> None:
    """Raise :class:`FilterError` when a grid of ``cell`` [m] and ``heading_bins`` over
    ``world`` has more than :data:`MAX_GRID_CELLS` cells or beacon-cells."""
    cell = float(params.get("cell", 0.2))
    nx = max(1, math.ceil(world.width / cell - 1e-9))
    ny = max(1, math.ceil(world.height / cell - 1e-9))
    nh = int(params.get("heading_bins", 36))
    nb = max(1, len(world.beacons))
    if nx * ny * nh > MAX_GRID_CELLS or nx * ny * nb > MAX_GRID_BEACON_CELLS:
        raise FilterError(
            f"{owner}: cell = {cell:g} m gives a grid of {nx:,} x {ny:,} x {nh} cells "
            f"({len(world.beacons)} beacons): expected at most {MAX_GRID_CELLS:,} cells and "
            f"{MAX_GRID_BEACON_CELLS:,} beacon-cells; use a larger cell")
