"""The scenario a recording carries: its text, label and folder, the map in its header, and the
scenario (or team) rebuilt from them."""

from __future__ import annotations

import base64
import zlib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from beacon_sim.core.files import read_user_text
from beacon_sim.core.occupancy import MAX_CELLS, MapError, OccupancyGrid, load_map
from beacon_sim.core.resources import scenario_dir
from beacon_sim.core.scenario import (
    MAX_SCENARIO_BYTES,
    Scenario,
    ScenarioError,
    TeamScenario,
    env_limit,
    is_team_document,
    parse_scenario,
    parse_team_scenario,
    parse_toml_text,
)
from beacon_sim.io.recording.format import TEAM_KIND, RecordingError, failure, is_number, short_text


def scenario_text(scenario: Scenario | TeamScenario) -> str:
    try:
        cap = env_limit("SCENARIO_BYTES", MAX_SCENARIO_BYTES)
    except ScenarioError as exc:
        raise RecordingError(str(exc)) from None
    return read_user_text(scenario.source, what="scenario file", cap=cap, error=RecordingError)


def scenario_label(source: str) -> str:
    """What a header's ``scenario_source`` says about the scenario file ``source`` (a path):
    a shipped scenario's name (``office``, ``team_sparse``: what ``beacon-sim play`` takes),
    or a user's file by its file name only (``my_room.toml``). Never a folder: a recording
    holds no path of the machine that made it."""
    path = Path(source)
    if path.suffix == ".toml":
        for shipped in (scenario_dir(), scenario_dir() / "team"):
            try:
                if path.resolve().parent == shipped.resolve() and path.is_file():
                    return path.stem
            except OSError:
                break
    return path.name


def scenario_folder(source: str | None) -> Path | None:
    """The folder of the scenario file a header's ``scenario_source`` names, for the files
    it names beside it (a map): a shipped scenario's (by name), the recorded folder of a
    file written before version 4 (a path), None for a user's file name (its folder is not
    recorded) or no source."""
    if not source:
        return None
    path = Path(source)
    if path.parent != Path("."):  # a path: a recording made before version 4
        return path.parent
    if path.suffix == ".toml":  # a user's file, by name only
        return None
    for shipped in (scenario_dir() / f"{source}.toml", scenario_dir() / "team" / f"{source}.toml"):
        if shipped.is_file():
            return shipped.parent
    return None


def rebuild_scenario(text: str, file: str, name: str, source: str | None = None,
                     map_grid: OccupancyGrid | None = None) -> Scenario:
    """A scenario from its stored text (the same checks and caps as loading the file); a
    map file it names is ``map_grid`` when given (the recorded map), else read from beside
    ``source``, the header's ``scenario_source`` (:func:`scenario_folder`)."""
    base = scenario_folder(source)
    return parse_scenario(parse_toml_text(text, file), file, name=name, base_dir=base,
                          map_grid=map_grid)


def map_file_name(text: str, file: str) -> str | None:
    """The ``world.map`` a scenario text names (a map_server YAML), or None."""
    world = parse_toml_text(text, file).get("world")
    name = world.get("map") if isinstance(world, dict) else None
    return name if isinstance(name, str) else None


def map_header(grid: OccupancyGrid, name: str) -> dict[str, Any]:
    """The header's ``"map"``: the occupancy grid the run used (``name``: the scenario's
    ``world.map``), so that a replay needs no map file. ``cells`` is the grid's int8 cells
    (row 0, the bottom row, first), zlib-compressed, in base64; ``sha256`` is
    :meth:`OccupancyGrid.sha256`."""
    rows, cols = grid.shape
    packed = base64.b64encode(zlib.compress(grid.cells.tobytes(), 9)).decode("ascii")
    return {"file": name, "shape": [rows, cols], "resolution": grid.resolution,
            "origin": list(grid.origin), "cells": packed, "sha256": grid.sha256()}


def recorded_map(path: Path, header: Mapping[str, Any]) -> OccupancyGrid | None:
    """The grid a header's ``"map"`` holds (None: the file has none, e.g. made before maps were
    recorded), checked against its digest (RecordingError naming what is wrong)."""
    m = header.get("map")
    if m is None:
        return None

    def bad(what: str) -> RecordingError:
        return failure(path, 1, f"corrupted header: map: {what}")

    if not isinstance(m, dict) or not isinstance(m.get("file"), str):
        raise bad("expected {file, shape, resolution, origin, cells, sha256}")
    shape, res, origin = m.get("shape"), m.get("resolution"), m.get("origin")
    if not (isinstance(shape, list) and len(shape) == 2
            and all(type(v) is int and v > 0 for v in shape) and shape[0] * shape[1] <= MAX_CELLS):
        raise bad(f"shape = {short_text(shape)} (expected [rows, cols], at most {MAX_CELLS:,} cells)")
    if not (isinstance(origin, list) and len(origin) == 3 and all(is_number(v) for v in origin)
            and is_number(res)):
        raise bad("resolution and origin [x, y, yaw] must be numbers")
    if not (isinstance(m.get("cells"), str) and isinstance(m.get("sha256"), str)):
        raise bad("cells (base64) and sha256 must be strings")
    n = shape[0] * shape[1]
    try:
        packed = base64.b64decode(m["cells"], validate=True)
        unpack = zlib.decompressobj()
        raw = unpack.decompress(packed, n + 1)
    except (ValueError, zlib.error):
        raise bad("cells are not zlib data in base64") from None
    if len(raw) != n or unpack.unconsumed_tail:
        raise bad(f"cells hold {len(raw):,}+ bytes, the shape {shape[0]}x{shape[1]} needs {n:,}")
    try:
        grid = OccupancyGrid(np.frombuffer(raw, dtype=np.int8).reshape(shape), float(res or 0.0),
                             (float(origin[0]), float(origin[1]), float(origin[2])))
    except MapError as exc:
        raise bad(str(exc)) from None
    if grid.sha256() != m["sha256"]:
        raise failure(path, 1, "the stored map was edited (its checksum map.sha256 differs): not "
                             "the map this run was recorded with")
    return grid


def disk_map_note(grid: OccupancyGrid, name: str, source: str | None) -> str | None:
    """A warning when the map file a recording's scenario names (beside ``source``, the
    header's ``scenario_source``: :func:`scenario_folder`) is missing, unreadable or holds
    another grid than the recorded one (None: the same, or not looked for: a user's
    scenario, whose folder a recording does not hold)."""
    path = Path(name)
    if not path.is_absolute():
        folder = scenario_folder(source)
        if folder is None:
            return None
        path = folder / path
    try:
        on_disk = load_map(path)
    except MapError as exc:
        return f"map file {path} cannot be read ({str(exc)[:120]}): replaying with the recorded map"
    if on_disk == grid:
        return None
    return (f"map file {path} differs from the recorded map (sha256 {on_disk.sha256()[:12]} on "
            f"disk, {grid.sha256()[:12]} recorded): replaying with the recorded map")


def rebuild_team_scenario(text: str, file: str, name: str) -> TeamScenario:
    """A team scenario from its stored text (the same checks as loading the file)."""
    data = parse_toml_text(text, file)
    if not is_team_document(data):
        raise ScenarioError(f"{file}: a team recording whose scenario has no [[robots]]")
    return parse_team_scenario(data, file, name=name)


def is_team_header(header: Mapping[str, Any]) -> bool:
    """Whether a recording's header is a team session's."""
    return header.get("kind") == TEAM_KIND

