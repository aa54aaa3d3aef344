"""Recordings: every run written as it goes, in JSON Lines, so it can be replayed bit for bit.

One JSON object per line (format described in docs/replay.md):

- line 1, the header: ``{"type": "header", "format": "beacon-sim-recording", "version": 2,
  "program_version", "created", "scenario_name", "scenario_source", "scenario_toml" (the
  full text of the scenario file), "scenario_sha256" (its checksum), "seed", "dt", "filters"
  (specs), "params" ({NAME: {KEY: VALUE}}, the ``--set`` overrides), "checkpoint_every"
  (ticks)}``;
- one line per tick: ``{"type": "tick", "k": tick, "u": [v, omega], "h": "8 hex digits",
  "r": "8 hex digits"}`` (truth and readings checksums)
  plus ``"c": [commands]`` when the user gave commands on that tick (:data:`COMMAND_KINDS`;
  their effect is in beacon_sim/runs/user_commands.py);
  ``h`` is the start of the truth checksum after the tick, so a replay names the first tick
  that differs;
- every ``checkpoint_every`` ticks (one simulated second): ``{"type": "checkpoint", "k",
  "time", "pose": [x, y, theta], "checksum", "readings_checksum"}``;
- last: ``{"type": "end", "ticks", "pose", "checksum", "readings_checksum"}``.

Version 1 files (no readings checksums, no scenario checksum) are still read; a replay says
they are verified for the truth only.

This module is the format: reading a file (:func:`load_recording`) and the pieces the writer
shares (:class:`beacon_sim.runs.recorder.Recorder` writes a file as a run goes). Reading
never executes code: ``json`` only.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
import math
import tomllib
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from beacon_sim.core.scenario import Scenario, ScenarioError, parse_scenario
from beacon_sim.core.types import Control
from beacon_sim.version import __version__

FORMAT_NAME = "beacon-sim-recording"
FORMAT_VERSION = 2
#: Versions this program reads. Version 1 files carry checksums of the truth only; version 2
#: adds the readings (``r`` per tick, ``readings_checksum``) and the scenario text
#: (``scenario_sha256`` in the header).
READ_VERSIONS = (1, 2)
#: Flush the file when this much simulated or wall time [s] has passed since the last flush.
FLUSH_EVERY_S = 0.5
RECORDINGS_DIR = "recordings"


class RecordingError(ValueError):
    """A recording file that cannot be read or replayed. The message is one line."""


#: The user commands a recording may hold, one dict each (applied by runs/user_commands.py):
#: ``{"kind": "kidnap", "pose": [x, y, theta]}`` (mouse click) or ``{"kind": "kidnap"}``
#: (random pose, K key); ``{"kind": "reset"}`` (R); ``{"kind": "global_reset"}`` (G);
#: ``{"kind": "toggle", "filter": NAME}`` (show / hide, display only).
COMMAND_KINDS = ("kidnap", "reset", "global_reset", "toggle")


def validate_command(cmd: Mapping) -> None:
    """Raise ValueError for a command this version does not know."""
    kind = cmd.get("kind")
    if kind not in COMMAND_KINDS:
        raise ValueError(f"unknown user command {kind!r}; expected one of {COMMAND_KINDS}")
    if kind == "kidnap" and "pose" in cmd and len(cmd["pose"]) != 3:
        raise ValueError(f"kidnap pose {cmd['pose']!r}: expected [x, y, theta]")


def default_recording_path(scenario_name: str, when: _dt.datetime | None = None) -> Path:
    """``recordings/<scenario>_<YYYYmmdd-HHMMSS>.jsonl`` under the current directory.

    A suffix ``-2``, ``-3``, ... is added when that name is taken (two runs in one second).
    """
    when = when or _dt.datetime.now()
    safe = "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in scenario_name) or "run"
    base = Path(RECORDINGS_DIR) / f"{safe}_{when:%Y%m%d-%H%M%S}"
    path = base.with_suffix(".jsonl")
    n = 2
    while path.exists():
        path = Path(f"{base}-{n}.jsonl")
        n += 1
    return path


def scenario_text(scenario: Scenario) -> str:
    try:
        return Path(scenario.source).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise RecordingError(f"{scenario.source}: cannot read the scenario file to record it: {exc}") \
            from None


def text_checksum(text: str) -> str:
    """SHA-256 (first 16 hex digits) of a scenario's text, as stored in a version 2 header."""
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def dumps(obj: Mapping[str, Any]) -> str:
    # Python's float repr round-trips exactly, so poses and controls come back bit for bit.
    return json.dumps(obj, separators=(",", ":"), allow_nan=True)




# --------------------------------------------------------------------------------------------
# Reading


@dataclass
class TickRecord:
    """One recorded tick: its number, control, user commands and short truth checksum."""

    tick: int
    control: Control
    commands: list[dict]
    short_checksum: str | None = None
    line: int = 0
    readings_checksum: str | None = None  # version 2: first 8 hex digits of the readings'



@dataclass
class Recording:
    """A recording read back. ``complete`` is False when the end line is missing (killed)."""

    path: Path
    header: dict[str, Any]
    scenario: Scenario
    ticks: list[TickRecord]
    checkpoints: dict[int, dict[str, Any]] = field(default_factory=dict)
    end: dict[str, Any] | None = None
    warnings: list[str] = field(default_factory=list)

    @property
    def seed(self) -> int:
        return int(self.header["seed"])

    @property
    def filters(self) -> list[str]:
        return list(self.header.get("filters", []))

    @property
    def params(self) -> dict[str, dict[str, Any]]:
        return {k: dict(v) for k, v in self.header.get("params", {}).items()}

    @property
    def complete(self) -> bool:
        return self.end is not None

    @property
    def version(self) -> int:
        """The file's format version (1: checksums of the truth only; 2: also the readings
        and the scenario text)."""
        return int(self.header["version"])


def rebuild_scenario(text: str, file: str, name: str) -> Scenario:
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{file}: not valid TOML: {exc}") from None
    return parse_scenario(data, file, name=name)


def _fail(path: Path, line: int, what: str) -> RecordingError:
    return RecordingError(f"{path}:{line}: {what}")


def _iter_lines(path: Path) -> Iterator[tuple[int, str, bool]]:
    """(line number, text, ends with newline) for each line of the file."""
    try:
        with path.open("r", encoding="utf-8", newline="") as f:
            for n, raw in enumerate(f, start=1):
                yield n, raw, raw.endswith("\n")
    except FileNotFoundError:
        raise RecordingError(f"{path}: no such recording") from None
    except IsADirectoryError:
        raise RecordingError(f"{path}: is a folder, not a recording") from None
    except UnicodeDecodeError as exc:
        raise RecordingError(f"{path}: not a text recording (byte {exc.start}: not UTF-8)") from None
    except OSError as exc:
        raise RecordingError(f"{path}: cannot read: {exc}") from None


def _check_header(path: Path, header: Any) -> None:
    if not isinstance(header, dict) or header.get("type") != "header" \
            or header.get("format") != FORMAT_NAME:
        raise _fail(path, 1, f"not a beacon-sim recording (the first line must be a "
                             f"{FORMAT_NAME!r} header)")
    version = header.get("version")
    if version not in READ_VERSIONS or isinstance(version, bool):
        raise _fail(path, 1, f"recording format version {version!r} is not supported by "
                             f"beacon-sim {__version__} (it reads versions "
                             f"{', '.join(map(str, READ_VERSIONS))})")
    need: dict[str, type | tuple[type, ...]] = {
        "scenario_toml": str, "scenario_name": str, "seed": int, "dt": (int, float),
        "filters": list, "params": dict}
    if version >= 2:
        need["scenario_sha256"] = str
    for key, typ in need.items():
        if not isinstance(header.get(key), typ) or isinstance(header.get(key), bool):
            value = repr(header.get(key))
            raise _fail(path, 1, f"corrupted header: {key} = {value[:60]}")
    if not 0 <= header["seed"] <= 2**63 - 1:
        raise _fail(path, 1, f"corrupted header: seed = {header['seed']!r}")
    if not all(isinstance(f, str) for f in header["filters"]) \
            or not all(isinstance(v, dict) for v in header["params"].values()):
        raise _fail(path, 1, "corrupted header: filters or params")
    if version >= 2 and text_checksum(header["scenario_toml"]) != header["scenario_sha256"]:
        raise _fail(path, 1, "the stored scenario was edited (its checksum scenario_sha256 "
                             "differs): not the scenario this run was recorded with")


def _number(x) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool)


def load_recording(path) -> Recording:
    """Read a recording (json only; nothing is executed).

    A truncated or unreadable *last* line (a killed program) is skipped with a warning in
    ``Recording.warnings``; anything else malformed raises :class:`RecordingError` naming
    the file and line.
    """
    path = Path(path)
    lines = list(_iter_lines(path))
    if not lines:
        raise RecordingError(f"{path}: empty file, not a recording")
    header = None
    ticks: list[TickRecord] = []
    checkpoints: dict[int, dict[str, Any]] = {}
    end = None
    notes: list[str] = []
    last = len(lines)
    for n, text, complete in lines:
        if not text.strip():
            continue
        try:
            obj = json.loads(text)
        except json.JSONDecodeError:
            obj = None
        if obj is None or not complete:
            if n == last and n > 1:
                notes.append(f"{path}:{n}: incomplete last line skipped (the program was "
                             "probably stopped while writing)")
                break
            if n == 1:
                raise _fail(path, 1, "corrupted header (not one complete JSON object)")
            raise _fail(path, n, "not valid JSON")
        if n == 1:
            _check_header(path, obj)
            header = obj
            continue
        if end is not None:
            raise _fail(path, n, "data after the end line")
        kind = obj.get("type") if isinstance(obj, dict) else None
        if kind == "tick":
            k, u, c = obj.get("k"), obj.get("u"), obj.get("c", [])
            if not (isinstance(k, int) and isinstance(u, list) and len(u) == 2
                    and all(_number(x) for x in u) and isinstance(c, list)):
                raise _fail(path, n, f"malformed tick line: {text.strip()[:80]}")
            expected = ticks[-1].tick + 1 if ticks else 1
            if k != expected:
                raise _fail(path, n, f"tick {k} where tick {expected} was expected")
            for cmd in c:
                try:
                    if not isinstance(cmd, dict):
                        raise ValueError(f"user command {cmd!r} is not an object")
                    validate_command(cmd)
                except ValueError as exc:
                    raise _fail(path, n, str(exc)) from None
            h, r = obj.get("h"), obj.get("r")
            if not (h is None or isinstance(h, str)) or not (r is None or isinstance(r, str)):
                raise _fail(path, n, f"malformed tick line: {text.strip()[:80]}")
            ticks.append(TickRecord(k, Control(float(u[0]), float(u[1])), c, h, n, r))
        elif kind == "checkpoint":
            if not isinstance(obj.get("k"), int) or not isinstance(obj.get("checksum"), str) \
                    or not isinstance(obj.get("readings_checksum", ""), str):
                raise _fail(path, n, "malformed checkpoint line")
            checkpoints[obj["k"]] = obj
        elif kind == "end":
            if not isinstance(obj.get("checksum"), str) \
                    or not isinstance(obj.get("readings_checksum", ""), str):
                raise _fail(path, n, "malformed end line")
            end = obj
        else:
            raise _fail(path, n, f"unknown line type {kind!r}")
    if header is None:
        raise _fail(path, 1, "corrupted header (missing)")
    if end is None:
        notes.append(f"{path}: no end line (the run was interrupted); replaying the "
                     f"{len(ticks)} complete ticks")
    file = f"{path} (scenario {header.get('scenario_source', header['scenario_name'])})"
    scenario = rebuild_scenario(header["scenario_toml"], file, header["scenario_name"])
    if not math.isclose(scenario.dt, float(header["dt"]), rel_tol=0, abs_tol=0):
        raise _fail(path, 1, f"corrupted header: dt {header['dt']} but the scenario says {scenario.dt}")
    scenario = replace(scenario, seed=int(header["seed"]))
    return Recording(path, header, scenario, ticks, checkpoints, end, notes)
