"""One TOML table read key by key (``Table``): each value checked (type, finite, in range), the
key path kept for the one-line error, unknown keys refused with a "did you mean"."""

from __future__ import annotations

import difflib
import enum
import math
from collections.abc import Sequence
from typing import Any, Final, NoReturn, overload

from beacon_sim.core.scenario.keys import generic_path, keys_at
from beacon_sim.core.scenario.limits import MAX_COORD
from beacon_sim.core.scenario.model import ScenarioError


class _Required(enum.Enum):
    """The type of ``_REQUIRED``: a key with no default must be in the file."""

    TOKEN = 0


_REQUIRED: Final = _Required.TOKEN


Vec3 = tuple[float, float, float]
Vec4 = tuple[float, float, float, float]


class Table:
    """Reads one TOML table, tracking the key path for error messages."""

    def __init__(self, data: Any, path: str, file: str):
        self.file = file
        self.path = path
        if not isinstance(data, dict):
            self.fail(path or "<top level>", data, "a table")
        self.data = data
        self.used: set[str] = set()
        # Unknown keys first: a misspelt table name should not be reported as a missing one.
        known = keys_at(generic_path(path))
        if known is not None:
            for k in data:
                if k not in known:
                    hint = difflib.get_close_matches(k, sorted(known), n=1)
                    extra = f" (did you mean {self.key(hint[0])!r}?)" if hint else ""
                    raise ScenarioError(f"{file}: unknown key {self.key(k)!r}{extra}")

    def key(self, name: str) -> str:
        return f"{self.path}.{name}" if self.path else name

    def fail(self, keypath: str, value: Any, expected: str) -> NoReturn:
        raise ScenarioError(f"{self.file}: {keypath} = {value!r}: expected {expected}")

    def has(self, name: str) -> bool:
        return name in self.data

    def raw(self, name: str, default: object = _REQUIRED) -> Any:
        self.used.add(name)
        if name not in self.data:
            if default is _REQUIRED:
                raise ScenarioError(f"{self.file}: missing key {self.key(name)}")
            return default
        return self.data[name]

    def number(self, name: str, default: float | _Required = _REQUIRED, *, lo: float = -math.inf,
               hi: float = math.inf, lo_open: bool = False, what: str | None = None,
               allow_inf: bool = False) -> float:
        """A finite number in ``[lo, hi]`` (``(lo, hi]`` when ``lo_open``); infinity only
        where ``allow_inf`` (e.g. ``max_range = inf``)."""
        value = self.raw(name, default)
        if default is not _REQUIRED and not self.has(name):
            return default
        ok = isinstance(value, int | float) and not isinstance(value, bool)
        if ok:
            try:
                x = float(value)
            except OverflowError:  # an integer too large for a float
                ok = False
        if ok:
            ok = (math.isfinite(x) or (allow_inf and x == math.inf)) \
                and (x > lo if lo_open else x >= lo) and (x <= hi or (allow_inf and x == math.inf))
        if not ok:
            rng = what or _range_text(lo, hi, lo_open)
            self.fail(self.key(name), value, f"a number {rng}" + (" or inf" if allow_inf else ""))
        return float(value)

    def integer(self, name: str, default: int | _Required = _REQUIRED, *, lo: int = -(2**63),
                hi: int = 2**63 - 1) -> int:
        value = self.raw(name, default)
        if default is not _REQUIRED and not self.has(name):
            return default
        if not isinstance(value, int) or isinstance(value, bool) or not lo <= value <= hi:
            self.fail(self.key(name), value, f"an integer {_range_text(lo, hi)}")
        return int(value)

    def boolean(self, name: str, default: bool | _Required = _REQUIRED) -> bool:
        value = self.raw(name, default)
        if not isinstance(value, bool):
            self.fail(self.key(name), value, "true or false")
        return value

    def string(self, name: str, default: str | _Required = _REQUIRED, *,
               choices: Sequence[str] | None = None) -> str:
        value = self.raw(name, default)
        if not isinstance(value, str):
            self.fail(self.key(name), value, "a string")
        if choices is not None and value not in choices:
            hint = difflib.get_close_matches(value, choices, n=1)
            extra = f" (did you mean {hint[0]!r}?)" if hint else ""
            self.fail(self.key(name), value, "one of " + ", ".join(map(repr, choices)) + extra)
        return value

    def _floats(self, name: str, n: int, lo: float, hi: float = 1e6) -> list[float]:
        """The key's list of ``n`` finite numbers, each in ``[lo, hi]`` (the key must be present)."""
        value = self.raw(name)
        ok = isinstance(value, list) and len(value) == n and all(
            isinstance(v, int | float) and not isinstance(v, bool) and finite_in(v, lo, hi)
            for v in value)
        if not ok:
            self.fail(self.key(name), value, f"a list of {n} finite numbers {_range_text(lo, hi)}")
        return [float(v) for v in value]

    @overload
    def vector3(self, name: str, default: Vec3 | _Required = ..., *, lo: float = ...,
                hi: float = ...) -> Vec3: ...

    @overload
    def vector3(self, name: str, default: None, *, lo: float = ..., hi: float = ...) -> Vec3 | None: ...

    def vector3(self, name: str, default: Vec3 | _Required | None = _REQUIRED, *,
                lo: float = -MAX_COORD, hi: float = MAX_COORD) -> Vec3 | None:
        """A list of 3 finite numbers in ``[lo, hi]``, e.g. a pose ``[x, y, theta]``."""
        if default is not _REQUIRED and not self.has(name):
            self.used.add(name)  # as raw() does
            return default
        x, y, z = self._floats(name, 3, lo, hi)
        return (x, y, z)

    def vector4(self, name: str, *, lo: float = -MAX_COORD, hi: float = MAX_COORD) -> Vec4:
        """A list of 4 finite numbers (required), e.g. bounds ``[xmin, ymin, xmax, ymax]``."""
        a, b, c, d = self._floats(name, 4, lo, hi)
        return (a, b, c, d)

    def sub(self, name: str, default: dict[str, Any] | _Required = _REQUIRED) -> Table:
        value = self.raw(name, {} if default is not _REQUIRED else _REQUIRED)
        return Table(value, self.key(name), self.file)

    def tables(self, name: str) -> list[Table]:
        value = self.raw(name, [])
        if not isinstance(value, list):
            self.fail(self.key(name), value, "an array of tables ([[...]])")
        return [Table(v, f"{self.key(name)}[{i}]", self.file) for i, v in enumerate(value)]

    def finish(self) -> None:
        unknown = [k for k in self.data if k not in self.used]
        if unknown:
            k = unknown[0]
            hint = difflib.get_close_matches(k, sorted(self.used | _known_keys(self)), n=1)
            extra = f" (did you mean {self.key(hint[0])!r}?)" if hint else ""
            raise ScenarioError(f"{self.file}: unknown key {self.key(k)!r}{extra}")


def _known_keys(table: Table) -> set[str]:
    return keys_at(generic_path(table.path)) or set()


def finite_in(v: float, lo: float, hi: float) -> bool:
    """Whether the number ``v`` (int or float) is finite and in ``[lo, hi]``."""
    try:
        x = float(v)
    except OverflowError:
        return False
    return math.isfinite(x) and lo <= x <= hi


def _range_text(lo: float, hi: float, lo_open: bool = False) -> str:
    if lo > -math.inf and hi < math.inf:
        return f"in {'(' if lo_open else '['}{lo:g}, {hi:g}]"
    if lo > -math.inf:
        return f"{'>' if lo_open else '>='} {lo:g}"
    if hi < math.inf:
        return f"<= {hi:g}"
    return ""


__all__ = ["Table", "Vec3", "Vec4", "finite_in"]
