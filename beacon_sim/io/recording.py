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

The header's ``"slip_model"`` (issue 25: ``"scaled"``, slip scaling with the command) names
the motion noise the run was made with; a file without it was made before and replays with
``"legacy"`` (noise at standstill). The tick's ``u`` is the command as given, also on a
tick the bumper stopped (the filters were told v = 0).

A team session (several robots, docs/multi-robot.md) is the same format with
``"kind": "team"`` in the header (and ``"robots"``: their names); the scenario is the team
file, ``filters`` team filter specs. Its tick lines add ``"d"`` (the index of the driven
robot) and ``"a": true`` when the driven robot's own driver chose ``u`` (autopilot), and its
commands name the robot they act on (:data:`TEAM_COMMAND_KINDS`); checkpoint and end lines
hold ``"poses"`` (one ``[x, y, theta]`` per robot) instead of ``"pose"``. The checksums are
the team's (:class:`beacon_sim.core.team.TeamSimulation` ``truth_checksum``, and
``beacon_sim.runs.recorder.TeamReadingsHash`` over every robot's readings). Headers without
``kind`` are single-robot recordings, unchanged.

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

from beacon_sim.core.motion import SLIP_MODELS
from beacon_sim.core.scenario import Scenario, ScenarioError, parse_scenario
from beacon_sim.core.simulation import RECORDED_BEFORE_SLIP_MODEL, scenario_with_slip
from beacon_sim.core.team import team_with_slip
from beacon_sim.core.team_scenario import TeamScenario, is_team_document, parse_team_scenario
from beacon_sim.core.types import Control
from beacon_sim.errors import BeaconSimError
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


class RecordingError(BeaconSimError):
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


#: The header's ``kind`` of a team session's recording (absent: one robot).
TEAM_KIND = "team"
#: The user commands a team recording may hold (applied by runs/team_live.py and
#: runs/team_replay.py): ``{"kind": "kidnap", "robot": i}`` (K: a random pose) or with
#: ``"pose": [x, y, theta]`` (click), robot i in team order; ``{"kind": "reset"}`` (R: every
#: team filter back to the initial beliefs); ``{"kind": "toggle", "filter": NAME}`` (display).
TEAM_COMMAND_KINDS = ("kidnap", "reset", "toggle")


def validate_team_command(cmd: Mapping, n_robots: int | None = None) -> None:
    """Raise ValueError for a team command this version does not know (or a robot index
    outside ``0 .. n_robots - 1``)."""
    kind = cmd.get("kind")
    if kind not in TEAM_COMMAND_KINDS:
        raise ValueError(f"unknown team command {kind!r}; expected one of {TEAM_COMMAND_KINDS}")
    if kind == "kidnap":
        robot = cmd.get("robot")
        if not isinstance(robot, int) or isinstance(robot, bool) or robot < 0 \
                or (n_robots is not None and robot >= n_robots):
            raise ValueError(f"kidnap of robot {robot!r}: expected a robot index"
                             + (f" from 0 to {n_robots - 1}" if n_robots else ""))
        if "pose" in cmd and not (isinstance(cmd["pose"], list | tuple) and len(cmd["pose"]) == 3
                                  and all(_number(x) and math.isfinite(x) for x in cmd["pose"])):
            raise ValueError(f"kidnap pose {cmd['pose']!r}: expected [x, y, theta]")
    if kind == "toggle" and not isinstance(cmd.get("filter"), str):
        raise ValueError(f"toggle of {cmd.get('filter')!r}: expected a filter name")


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


def scenario_text(scenario: Scenario | TeamScenario) -> str:
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
class TeamTickRecord(TickRecord):
    """One recorded team tick: also the driven robot (index in team order) and whether its
    own driver chose ``control`` (autopilot: a replay lets the driver choose again, so the
    driver's state, e.g. its next waypoint, follows as it did live)."""

    driven: int = 0
    autopilot: bool = False


class _HeaderFields:
    """What single-robot and team recordings read from their header the same way."""

    header: dict[str, Any]
    end: dict[str, Any] | None

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


@dataclass
class Recording(_HeaderFields):
    """A recording read back. ``complete`` is False when the end line is missing (killed)."""

    path: Path
    header: dict[str, Any]
    scenario: Scenario
    ticks: list[TickRecord]
    checkpoints: dict[int, dict[str, Any]] = field(default_factory=dict)
    end: dict[str, Any] | None = None
    warnings: list[str] = field(default_factory=list)


@dataclass
class TeamRecording(_HeaderFields):
    """A team session's recording read back (``team``: the team scenario rebuilt from the
    stored text, with the recorded seed)."""

    path: Path
    header: dict[str, Any]
    team: TeamScenario
    ticks: list[TeamTickRecord]
    checkpoints: dict[int, dict[str, Any]] = field(default_factory=dict)
    end: dict[str, Any] | None = None
    warnings: list[str] = field(default_factory=list)

    @property
    def scenario(self) -> TeamScenario:
        """The team scenario (named as a :class:`Recording`'s, for code that reads ``dt``)."""
        return self.team


def rebuild_scenario(text: str, file: str, name: str) -> Scenario:
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{file}: not valid TOML: {exc}") from None
    return parse_scenario(data, file, name=name)


def rebuild_team_scenario(text: str, file: str, name: str) -> TeamScenario:
    """A team scenario from its stored text (the same checks as loading the file)."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{file}: not valid TOML: {exc}") from None
    if not is_team_document(data):
        raise ScenarioError(f"{file}: a team recording whose scenario has no [[robots]]")
    return parse_team_scenario(data, file, name=name)


def is_team_header(header: Mapping[str, Any]) -> bool:
    """Whether a recording's header is a team session's."""
    return header.get("kind") == TEAM_KIND


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
    kind = header.get("kind")
    if kind is not None and kind != TEAM_KIND:
        raise _fail(path, 1, f"recording kind {str(kind)[:40]!r} is not supported by beacon-sim "
                             f"{__version__} (it reads single-robot and {TEAM_KIND!r} recordings)")
    if kind == TEAM_KIND and version < 2:
        raise _fail(path, 1, "corrupted header: a team recording is version 2 or later")
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


def _tick_line(path: Path, n: int, text: str, obj: dict, expected: int,
               team: bool) -> TickRecord:
    """One tick line, checked (``team``: also the driven robot, autopilot, team commands)."""
    k, u, c = obj.get("k"), obj.get("u"), obj.get("c", [])
    if not (isinstance(k, int) and isinstance(u, list) and len(u) == 2
            and all(_number(x) for x in u) and isinstance(c, list)):
        raise _fail(path, n, f"malformed tick line: {text.strip()[:80]}")
    if k != expected:
        raise _fail(path, n, f"tick {k} where tick {expected} was expected")
    for cmd in c:
        try:
            if not isinstance(cmd, dict):
                raise ValueError(f"user command {cmd!r} is not an object")
            (validate_team_command if team else validate_command)(cmd)
        except ValueError as exc:
            raise _fail(path, n, str(exc)) from None
    h, r = obj.get("h"), obj.get("r")
    if not (h is None or isinstance(h, str)) or not (r is None or isinstance(r, str)):
        raise _fail(path, n, f"malformed tick line: {text.strip()[:80]}")
    control = Control(float(u[0]), float(u[1]))
    if not team:
        return TickRecord(k, control, c, h, n, r)
    d, a = obj.get("d"), obj.get("a", False)
    if not isinstance(d, int) or isinstance(d, bool) or d < 0 or not isinstance(a, bool):
        raise _fail(path, n, f"malformed team tick line (d: the driven robot, a: autopilot): "
                             f"{text.strip()[:80]}")
    return TeamTickRecord(k, control, c, h, n, r, driven=d, autopilot=a)


def _state_line_ok(obj: dict, team: bool) -> bool:
    """A checkpoint or end line's checksums (and, for a team, its poses) have the right types."""
    if not isinstance(obj.get("checksum"), str) or not isinstance(obj.get("readings_checksum", ""), str):
        return False
    return not team or (isinstance(obj.get("poses"), list)
                        and all(isinstance(p, list) and len(p) == 3 and all(_number(x) for x in p)
                                for p in obj["poses"]))


def _read_file(path: Path) -> tuple[dict[str, Any], list[Any], dict[int, dict[str, Any]],
                                    dict[str, Any] | None, list[str]]:
    """(header, ticks, checkpoints, end, warnings) of a recording of either kind (json only;
    nothing is executed). A truncated or unreadable *last* line is skipped with a warning;
    anything else malformed raises :class:`RecordingError` naming the file and line."""
    lines = list(_iter_lines(path))
    if not lines:
        raise RecordingError(f"{path}: empty file, not a recording")
    header: dict[str, Any] | None = None
    team = False
    ticks: list[Any] = []
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
            team = is_team_header(obj)
            continue
        if end is not None:
            raise _fail(path, n, "data after the end line")
        kind = obj.get("type") if isinstance(obj, dict) else None
        if kind == "tick":
            ticks.append(_tick_line(path, n, text, obj, ticks[-1].tick + 1 if ticks else 1, team))
        elif kind == "checkpoint":
            if not isinstance(obj.get("k"), int) or not _state_line_ok(obj, team):
                raise _fail(path, n, "malformed checkpoint line")
            checkpoints[obj["k"]] = obj
        elif kind == "end":
            if not _state_line_ok(obj, team):
                raise _fail(path, n, "malformed end line")
            end = obj
        else:
            raise _fail(path, n, f"unknown line type {kind!r}")
    if header is None:
        raise _fail(path, 1, "corrupted header (missing)")
    if end is None:
        notes.append(f"{path}: no end line (the run was interrupted); replaying the "
                     f"{len(ticks)} complete ticks")
    return header, ticks, checkpoints, end, notes


def _check_dt(path: Path, header: dict[str, Any], dt: float) -> None:
    if not math.isclose(dt, float(header["dt"]), rel_tol=0, abs_tol=0):
        raise _fail(path, 1, f"corrupted header: dt {header['dt']} but the scenario says {dt}")


def _slip_model(path: Path, header: Mapping[str, Any]) -> str:
    """The header's "slip_model" (issue 25); "legacy" for a file made before it."""
    model = header.get("slip_model", RECORDED_BEFORE_SLIP_MODEL)
    if model not in SLIP_MODELS:
        raise _fail(path, 1, f"corrupted header: slip_model = {model!r} (expected "
                             f"{' or '.join(repr(m) for m in SLIP_MODELS)})")
    return str(model)


def load_recording(path) -> Recording:
    """Read a single-robot recording (json only; nothing is executed).

    A truncated or unreadable *last* line (a killed program) is skipped with a warning in
    ``Recording.warnings``; anything else malformed raises :class:`RecordingError` naming
    the file and line. A team session's recording is a RecordingError here (read it with
    :func:`load_team_recording` or :func:`load_any_recording`).
    """
    path = Path(path)
    header, ticks, checkpoints, end, notes = _read_file(path)
    if is_team_header(header):
        raise _fail(path, 1, "a team session's recording: beacon-sim replay reads it "
                             "(this command takes single-robot recordings)")
    file = f"{path} (scenario {header.get('scenario_source', header['scenario_name'])})"
    scenario = rebuild_scenario(header["scenario_toml"], file, header["scenario_name"])
    _check_dt(path, header, scenario.dt)
    scenario = replace(scenario_with_slip(scenario, _slip_model(path, header)), seed=int(header["seed"]))
    return Recording(path, header, scenario, ticks, checkpoints, end, notes)


def load_team_recording(path) -> TeamRecording:
    """Read a team session's recording (json only; nothing is executed; the same rules as
    :func:`load_recording`, and every robot index in range)."""
    path = Path(path)
    header, ticks, checkpoints, end, notes = _read_file(path)
    if not is_team_header(header):
        raise _fail(path, 1, "a single-robot recording, not a team session's")
    file = f"{path} (scenario {header.get('scenario_source', header['scenario_name'])})"
    team = rebuild_team_scenario(header["scenario_toml"], file, header["scenario_name"])
    _check_dt(path, header, team.dt)
    team = team_with_slip(team, _slip_model(path, header))
    n = len(team.robots)
    for rec in ticks:
        try:
            if rec.driven >= n:
                raise ValueError(f"driven robot {rec.driven}: expected an index from 0 to {n - 1}")
            for cmd in rec.commands:
                validate_team_command(cmd, n)
        except ValueError as exc:
            raise _fail(path, rec.line, str(exc)) from None
    for k, obj in [*checkpoints.items(), (-1, end or {"poses": [None] * n})]:
        if len(obj["poses"]) != n:
            raise _fail(path, 1, f"corrupted {'end' if k < 0 else f'checkpoint {k}'}: "
                                 f"{len(obj['poses'])} poses for {n} robots")
    team = replace(team, seed=int(header["seed"]))
    return TeamRecording(path, header, team, ticks, checkpoints, end, notes)


def load_any_recording(path) -> Recording | TeamRecording:
    """A recording of either kind (single-robot or team), by its header."""
    path = Path(path)
    for _, text, _ in _iter_lines(path):
        try:
            first = json.loads(text)
        except json.JSONDecodeError:
            first = None
        if isinstance(first, dict) and is_team_header(first):
            return load_team_recording(path)
        break
    return load_recording(path)
