"""The documented range of every built-in filter's parameters, and the bounds on what a
filter may allocate, checked when a filter is built (scenario ``[filters.NAME]``, ``--set``,
a recording's parameters): a value outside is a one-line :class:`FilterError`.

Ranges are inclusive ``(lo, hi)``; every float must also be finite and every integer
parameter an integer (docs/filters.md, "Parameter ranges").
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from beacon_sim.core.world import World
from beacon_sim.filters.base import FilterError

#: Most particles a particle filter may hold (positions and weights: about 50 MB).
MAX_PARTICLES = 1_000_000
#: Most cells (x cells * y cells * heading bins) of a grid, and most (beacon, x-y cell)
#: pairs its precomputed geometry may hold: each array of that size is 160 MB.
MAX_GRID_CELLS = 20_000_000
MAX_GRID_BEACON_CELLS = 20_000_000

_PF = "beacon_sim.filters.particle:ParticleFilter"
_GRID = "beacon_sim.filters.histogram:HistogramFilter"

RANGES: dict[str, dict[str, tuple[float, float]]] = {
    _PF: {
        "n_particles": (1, MAX_PARTICLES), "n_min": (1, MAX_PARTICLES), "n_max": (1, MAX_PARTICLES),
        "ess_threshold": (0.0, 1.0), "alpha_slow": (0.0, 1.0), "alpha_fast": (0.0, 1.0),
        "inject_max": (0.0, 1.0), "kld_epsilon": (1e-6, 1.0), "kld_z": (0.0, 10.0),
        "kld_bin_xy": (1e-3, 1e3), "kld_bin_theta": (1e-3, 2 * math.pi), "ver_max": (0.0, 1e12),
        "roughen": (0.0, 100.0), "cluster_cell": (1e-3, 1e6), "cluster_radius": (1e-3, 1e6),
        "heading_k_a": (0.0, 100.0), "temper_ess": (0.0, 1.0),
    },
    _GRID: {
        "cell": (1e-3, 1e3), "heading_bins": (4, 3600), "floor": (0.0, 0.999),
        "blur_min": (1e-6, 1e3), "grid_noise": (0.0, 1e6),
    },
    "beacon_sim.filters.ekf:ExtendedKalmanFilter": {"gate_chi2": (0.0, 1e6)},
    "beacon_sim.filters.ukf:UnscentedKalmanFilter": {
        "alpha": (1e-4, 10.0), "beta": (0.0, 100.0), "kappa": (-2.5, 100.0), "gate_chi2": (0.0, 1e6),
    },
    # team filters (filters/team.py)
    "beacon_sim.filters.team:CentralisedEKF": {"gate_chi2": (0.0, 1e6)},
    "beacon_sim.filters.team:PairwiseDecentralisedEKF": {"gate_chi2": (0.0, 1e6)},
    "beacon_sim.filters.team:CovarianceIntersectionTeam": {"gate_chi2": (0.0, 1e6)},
}


def class_key(cls: type) -> str:
    """``module:QualName`` of a filter class (how ``RANGES`` names it)."""
    return f"{cls.__module__}:{cls.__qualname__}"


def check_value(cls: type, key: str, value: Any, default: Any) -> None:
    """Raise :class:`FilterError` when ``value`` is not a finite number (for a number
    parameter), not an integer (for an integer one) or outside the documented range."""
    name = cls.__name__
    if isinstance(default, int) and not isinstance(default, bool) and not isinstance(value, int):
        raise FilterError(f"{name}: parameter {key} = {value!r}: expected an integer like {default!r}")
    if isinstance(default, float) and isinstance(value, int | float) and not isinstance(value, bool):
        try:
            finite = math.isfinite(float(value))
        except OverflowError:
            finite = False
        if not finite:
            raise FilterError(f"{name}: parameter {key} = {value!r}: expected a finite number")
    rng = RANGES.get(class_key(cls), {}).get(key)
    if rng is not None and isinstance(value, int | float) and not isinstance(value, bool):
        lo, hi = rng
        if not lo <= value <= hi:
            raise FilterError(f"{name}: parameter {key} = {value!r}: expected a number in "
                              f"[{lo:g}, {hi:g}]")


def check_params(cls: type, params: Mapping[str, Any], world: World) -> None:
    """Every given parameter of a class with ``defaults`` (:class:`FilterBase`) checked by
    :func:`check_value`, then :func:`check_resources`."""
    defaults = getattr(cls, "defaults", None)
    if isinstance(defaults, Mapping):
        for key, value in params.items():
            if key in defaults:
                check_value(cls, key, value, defaults[key])
    check_resources(cls, {**(defaults if isinstance(defaults, Mapping) else {}), **params}, world)


def check_resources(cls: type, params: Mapping[str, Any], world: World) -> None:
    """Raise :class:`FilterError` when a built-in filter's parameters ask for more memory
    than :data:`MAX_PARTICLES` / :data:`MAX_GRID_CELLS` allow in this world."""
    key = class_key(cls)
    if key == _PF:
        n = max(int(params.get(k, 0)) for k in ("n_particles", "n_max"))
        if n > MAX_PARTICLES:
            raise FilterError(f"{cls.__name__}: {n:,} particles: expected at most {MAX_PARTICLES:,}")
    elif key == _GRID:
        cell = float(params.get("cell", 0.2))
        nx = max(1, math.ceil(world.width / cell - 1e-9))
        ny = max(1, math.ceil(world.height / cell - 1e-9))
        nh = int(params.get("heading_bins", 36))
        nb = max(1, len(world.beacons))
        if nx * ny * nh > MAX_GRID_CELLS or nx * ny * nb > MAX_GRID_BEACON_CELLS:
            raise FilterError(
                f"{cls.__name__}: cell = {cell:g} m gives a grid of {nx:,} x {ny:,} x {nh} cells "
                f"({len(world.beacons)} beacons): expected at most {MAX_GRID_CELLS:,} cells and "
                f"{MAX_GRID_BEACON_CELLS:,} beacon-cells; use a larger cell")
