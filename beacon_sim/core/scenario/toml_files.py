"""A user's TOML file read safely: its size capped before it is read, its document's depth,
size and integers checked after, every failure one ``ScenarioError`` line."""

from __future__ import annotations

import hashlib
import os
import tomllib
from pathlib import Path
from typing import Any

from beacon_sim.core.files import read_user_text
from beacon_sim.core.scenario.limits import MAX_INT_DIGITS, MAX_NESTING, MAX_SCENARIO_BYTES
from beacon_sim.core.scenario.model import ScenarioError
from beacon_sim.errors import BeaconSimError


def env_limit(name: str, default: int) -> int:
    """A cap: ``default``, or the whole number in the environment variable
    ``BEACON_SIM_MAX_<name>`` (to raise it)."""
    var = f"BEACON_SIM_MAX_{name}"
    raw = os.environ.get(var)
    if raw is None:
        return default
    try:
        value = int(raw.replace("_", ""))
    except ValueError:
        value = 0
    if value < 1:
        raise ScenarioError(f"{var}={raw[:40]!r}: expected a positive whole number (a cap; "
                            f"the default is {default:,})")
    return value


def document_shape(obj: Any, limit: int) -> tuple[int, int]:
    """(how deep arrays and tables nest in ``obj``, counted up to ``limit + 1``; the largest
    absolute integer in it), so that a hostile document costs no more than the cap."""
    depth, level, biggest = 0, [obj], 0
    while level and depth <= limit:
        nxt: list[Any] = []
        for x in level:
            if isinstance(x, dict):
                nxt.extend(x.values())
            elif isinstance(x, list | tuple):
                nxt.extend(x)
            elif type(x) is int and not -biggest <= x <= biggest:
                biggest = abs(x)
        if not nxt:
            break
        depth += 1
        level = nxt
    return depth, biggest


def check_document(data: Any, file: str) -> None:
    """The caps every decoded scenario (or recording line) obeys: nesting depth
    (``MAX_NESTING``) and integer size (``MAX_INT_DIGITS``); ScenarioError, one line."""
    limit = env_limit("NESTING", MAX_NESTING)
    digits = env_limit("INT_DIGITS", MAX_INT_DIGITS)
    depth, biggest = document_shape(data, limit)
    if depth > limit:
        raise ScenarioError(f"{file}: arrays or tables nested deeper than {limit} levels "
                            f"(BEACON_SIM_MAX_NESTING raises the cap)")
    if biggest >= 10**digits:
        raise ScenarioError(f"{file}: an integer of more than {digits} digits (at most {digits}; "
                            f"BEACON_SIM_MAX_INT_DIGITS raises the cap)")


def parse_toml_text(text: str, file: str) -> dict[str, Any]:
    """A TOML document decoded and checked against the caps (ScenarioError, one line)."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{file}: not valid TOML: {exc}") from None
    except RecursionError:
        raise ScenarioError(f"{file}: arrays or tables nested too deep to read (at most "
                            f"{env_limit('NESTING', MAX_NESTING)} levels)") from None
    except ValueError as exc:  # e.g. an integer over Python's 4,300-digit limit
        raise ScenarioError(f"{file}: not valid TOML: {str(exc).splitlines()[0][:100]}") from None
    check_document(data, file)
    return data


def read_user_toml(path: str | Path, *, what: str, cap: int,
                   error: type[BeaconSimError] = ScenarioError, hint: str = "") -> dict[str, Any]:
    """A user's TOML file other than a scenario (a grade config): a regular file within
    ``cap`` bytes (:func:`~beacon_sim.core.files.read_user_text`), decoded and checked
    against the same caps on nesting and integers as a scenario; ``error``, one line."""
    text = read_user_text(path, what=what, cap=cap, error=error, hint=hint)
    try:
        return parse_toml_text(text, str(path))
    except ScenarioError as exc:
        raise error(str(exc)) from None


#: The last document read (key: path and the SHA-256 of its text), so that telling a team
#: file from a single-robot one and then loading it parses the file once.
_last_read: list[Any] = [None, None]


def read_toml(path: Path) -> dict[str, Any]:
    """A scenario file's TOML document: its size checked first (``MAX_SCENARIO_BYTES``),
    then decoded and checked (ScenarioError, one line). Callers do not modify it."""
    text = read_user_text(path, what="scenario file", cap=env_limit("SCENARIO_BYTES", MAX_SCENARIO_BYTES),
                          error=ScenarioError, hint=" (BEACON_SIM_MAX_SCENARIO_BYTES raises the cap)")
    key = (str(path), hashlib.sha256(text.encode("utf-8")).digest())
    if _last_read[0] == key:
        return _last_read[1]
    data = parse_toml_text(text, str(path))
    _last_read[:] = [key, data]
    return data


__all__ = [
    "check_document",
    "document_shape",
    "env_limit",
    "parse_toml_text",
    "read_toml",
    "read_user_toml",
]
