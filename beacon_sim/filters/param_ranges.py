"""The checks made when a filter is built (scenario ``[filters.NAME]``, ``--set``, a
recording's parameters), read from the built-in filters' records (filters/registry.py): a
value outside its documented range, not finite, or not an integer for an integer parameter
is a one-line :class:`FilterError`; so is a built-in filter asked to allocate more than
its memory bound (docs/filters.md, "Parameter ranges").
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from beacon_sim.core.world import World
from beacon_sim.filters.params import MAX_GRID_BEACON_CELLS, MAX_GRID_CELLS, MAX_PARTICLES, Param
from beacon_sim.filters.registry import class_key, record_for_class


def check_value(cls: type, key: str, value: Any, default: Any) -> None:
    """Raise :class:`FilterError` when ``value`` is not a finite number (for a number
    parameter), not an integer (for an integer one) or outside the documented range."""
    record = record_for_class(cls)
    Param.of(default, record.ranges.get(key) if record else None).check(cls.__name__, key, value)


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
    than its record's bound allows in this world (:data:`MAX_PARTICLES`,
    :data:`MAX_GRID_CELLS`)."""
    record = record_for_class(cls)
    if record is not None and record.memory is not None:
        record.memory(cls.__name__, params, world)


__all__ = ["MAX_GRID_BEACON_CELLS", "MAX_GRID_CELLS", "MAX_PARTICLES", "check_params",
           "check_resources", "check_value", "class_key"]
