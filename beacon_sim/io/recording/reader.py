"""Reading a recording: every line checked (caps, JSON, the header, ticks in order, checkpoints,
the signature) into a :class:`Recording`; a file cut short reads to its last complete tick."""

from __future__ import annotations

import hmac
import io
import json
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from beacon_sim.core.files import open_user_file
from beacon_sim.core.motion import SLIP_MODELS
from beacon_sim.core.scenario import (
    MAX_ROBOTS,
    MAX_SENSORS,
    MAX_SPEED,
    Scenario,
    ScenarioError,
    TeamScenario,
    check_document,
    env_limit,
    team_of_one,
)
from beacon_sim.core.simulation import RECORDED_BEFORE_SLIP_MODEL, scenario_with_slip
from beacon_sim.core.team import team_with_slip
from beacon_sim.core.types import Control
from beacon_sim.io.recording.format import (
    FORMAT_NAME,
    HEADER_KEYS,
    KEY_VARIABLE,
    MAX_COMMANDS,
    MAX_DESCRIPTION_CHARS,
    MAX_LINE_CHARS,
    MAX_RECORDED_TURN,
    MAX_RECORDING_BYTES,
    MODEL_KEYS,
    READ_VERSIONS,
    TEAM_KIND,
    VALUES_PER_ROBOT,
    FileParts,
    RecordingError,
    TickRecord,
    failure,
    finite_within,
    is_number,
    short_text,
    validate_command,
)
from beacon_sim.io.recording.integrity import Signer, is_fingerprint, recording_key, text_checksum
from beacon_sim.io.recording.scenario_text import (
    disk_map_note,
    is_team_header,
    rebuild_scenario,
    rebuild_team_scenario,
    recorded_map,
    scenario_folder,
)
from beacon_sim.version import __version__


@dataclass
class Recording:
    """A recording read back, of any number of robots: ``team`` is the scenario rebuilt from
    the stored text with the recorded seed, as a team (a single robot's file: a team of one,
    ``team.solo``). ``complete`` is False when the end line is missing (killed)."""

    path: Path
    header: dict[str, Any]
    team: TeamScenario
    ticks: list[TickRecord]
    checkpoints: dict[int, dict[str, Any]] = field(default_factory=dict)
    end: dict[str, Any] | None = None
    warnings: list[str] = field(default_factory=list)
    parts: FileParts = field(default_factory=FileParts)

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
        and the scenario text; 3: the filter settings and estimate digests; 4: the maths
        fingerprint and the estimates' values)."""
        return int(self.header["version"])

    @property
    def maths(self) -> str | None:
        """The maths fingerprint of the machine that made the file (None: made before
        beacon-sim stored it, version 3 and older)."""
        fp = self.header.get("maths")
        return fp if is_fingerprint(fp) else None

    @property
    def maths_description(self) -> str:
        """The recording machine's maths in words (``numpy 2.4.6, x86_64, AVX512_SPR``)."""
        return str(self.header.get("maths_description") or "not recorded")

    @property
    def scenario(self) -> Scenario:
        """The first robot's scenario: a single robot's file, its scenario itself (the
        world, ``dt`` and the seed are every robot's)."""
        return self.team.robots[0].scenario

    @property
    def is_team(self) -> bool:
        """Whether the file is in a team's format (``"kind": "team"``) rather than a single
        robot's (today's format of a team of one)."""
        return is_team_header(self.header)

    @property
    def n_robots(self) -> int:
        return self.team.n_robots


def _iter_lines(path: Path) -> Iterator[tuple[int, str, bool]]:
    """(line number, text, ends with newline) for each line of the file, within the caps
    (:data:`MAX_RECORDING_BYTES`, :data:`MAX_LINE_CHARS`)."""
    try:
        size_cap = env_limit("RECORDING_BYTES", MAX_RECORDING_BYTES)
        line_cap = env_limit("LINE_CHARS", MAX_LINE_CHARS)
    except ScenarioError as exc:
        raise RecordingError(str(exc)) from None
    raw_file = open_user_file(path, what="recording", cap=size_cap, error=RecordingError,
                              hint=" (BEACON_SIM_MAX_RECORDING_BYTES raises the cap)")
    try:
        with io.TextIOWrapper(raw_file, encoding="utf-8", newline="") as f:
            n = 0
            while raw := f.readline(line_cap + 1):
                n += 1
                if len(raw) > line_cap:
                    raise RecordingError(f"{path}:{n}: a line longer than {line_cap:,} characters "
                                         "(BEACON_SIM_MAX_LINE_CHARS raises the cap)")
                yield n, raw, raw.endswith("\n")
    except UnicodeDecodeError as exc:
        raise RecordingError(f"{path}: not a text recording (byte {exc.start}: not UTF-8)") from None
    except OSError as exc:
        raise RecordingError(f"{path}: cannot read: {exc}") from None


def _decode(path: Path, n: int, text: str) -> Any:
    """One line's JSON (None when it is not valid JSON), within the caps on nesting and
    integers (RecordingError naming the line)."""
    try:
        obj = json.loads(text)
    except json.JSONDecodeError:
        return None
    except RecursionError:
        raise failure(path, n, "nested too deep to read") from None
    except ValueError as exc:  # an integer over Python's 4,300-digit limit
        raise failure(path, n, f"not a usable number: {str(exc).splitlines()[0][:80]}") from None
    try:
        check_document(obj, f"{path}:{n}")
    except ScenarioError as exc:
        raise RecordingError(str(exc)) from None
    return obj


def _check_header(path: Path, header: Any) -> None:
    if not isinstance(header, dict) or header.get("type") != "header" \
            or header.get("format") != FORMAT_NAME:
        raise failure(path, 1, f"not a beacon-sim recording (the first line must be a "
                             f"{FORMAT_NAME!r} header)")
    version = header.get("version")
    if version not in READ_VERSIONS or isinstance(version, bool):
        raise failure(path, 1, f"recording format version {short_text(version)} is not supported by "
                             f"beacon-sim {__version__} (it reads versions "
                             f"{', '.join(map(str, READ_VERSIONS))})")
    kind = header.get("kind")
    if kind is not None and kind != TEAM_KIND:
        raise failure(path, 1, f"recording kind {str(kind)[:40]!r} is not supported by beacon-sim "
                             f"{__version__} (it reads single-robot and {TEAM_KIND!r} recordings)")
    if kind == TEAM_KIND and version < 2:
        raise failure(path, 1, "corrupted header: a team recording is version 2 or later")
    if version >= 3:
        unknown = sorted(k for k in header if k not in HEADER_KEYS and k not in MODEL_KEYS)
        if unknown:
            raise failure(path, 1, f"corrupted header: unknown key {unknown[0][:40]!r} (a version 3 "
                                 "header holds the keys of io/recording.py HEADER_KEYS and MODEL_KEYS)")
    need: dict[str, type | tuple[type, ...]] = {
        "scenario_toml": str, "scenario_name": str, "seed": int, "dt": (int, float),
        "filters": list, "params": dict}
    if version >= 2:
        need["scenario_sha256"] = str
    for key, typ in need.items():
        if not isinstance(header.get(key), typ) or isinstance(header.get(key), bool):
            raise failure(path, 1, f"corrupted header: {key} = {short_text(header.get(key))}")
    if not 0 <= header["seed"] <= 2**63 - 1:
        raise failure(path, 1, f"corrupted header: seed = {short_text(header['seed'])}")
    if not math.isfinite(header["dt"]):
        raise failure(path, 1, f"corrupted header: dt = {header['dt']!r}")
    if len(header["filters"]) > MAX_SENSORS or len(header["params"]) > MAX_SENSORS:
        raise failure(path, 1, f"corrupted header: more than {MAX_SENSORS} filters or params")
    if not all(isinstance(f, str) for f in header["filters"]) \
            or not all(isinstance(v, dict) for v in header["params"].values()):
        raise failure(path, 1, "corrupted header: filters or params")
    if "signed" in header and not isinstance(header["signed"], bool):
        raise failure(path, 1, f"corrupted header: signed = {short_text(header['signed'])}")
    if version >= 4 and not is_fingerprint(header.get("maths")):
        raise failure(path, 1, f"corrupted header: maths = {short_text(header.get('maths'))} (expected "
                             "16 hex digits: the maths fingerprint of the machine that made it)")
    description = header.get("maths_description", "")
    if not isinstance(description, str) or len(description) > MAX_DESCRIPTION_CHARS:
        raise failure(path, 1, f"corrupted header: maths_description = {short_text(description)} "
                             f"(expected a string of at most {MAX_DESCRIPTION_CHARS} characters)")
    if version >= 2 and text_checksum(header["scenario_toml"], version) != header["scenario_sha256"]:
        raise failure(path, 1, "the stored scenario was edited (its checksum scenario_sha256 "
                             "differs): not the scenario this run was recorded with")


def _tick_line(path: Path, n: int, text: str, obj: dict, expected: int,
               team: bool) -> TickRecord:
    """One tick line, checked (``team``: also the driven robot, autopilot, team commands):
    the control finite and within MAX_SPEED [m/s] / MAX_RECORDED_TURN [rad/s], at most
    MAX_COMMANDS user commands, each valid."""
    k, u, c = obj.get("k"), obj.get("u"), obj.get("c", [])
    if not (type(k) is int and isinstance(u, list) and len(u) == 2
            and all(is_number(x) for x in u) and isinstance(c, list)):
        raise failure(path, n, f"malformed tick line: {text.strip()[:80]}")
    if k != expected:
        raise failure(path, n, f"tick {short_text(k)} where tick {expected} was expected")
    if not (finite_within(u[0], MAX_SPEED) and finite_within(u[1], MAX_RECORDED_TURN)):
        raise failure(path, n, f"control u = [{short_text(u[0])}, {short_text(u[1])}]: expected finite "
                             f"numbers, |v| <= {MAX_SPEED:g} m/s and |omega| <= "
                             f"{MAX_RECORDED_TURN:g} rad/s")
    if len(c) > MAX_COMMANDS:
        raise failure(path, n, f"{len(c):,} user commands on one tick: expected at most {MAX_COMMANDS}")
    for cmd in c:
        try:
            if not isinstance(cmd, dict):
                raise ValueError(f"user command {short_text(cmd)} is not an object")
            validate_command(cmd, 0 if team else None)
        except ValueError as exc:
            raise failure(path, n, str(exc)) from None
    h, r = obj.get("h"), obj.get("r")
    if not (h is None or isinstance(h, str)) or not (r is None or isinstance(r, str)):
        raise failure(path, n, f"malformed tick line: {text.strip()[:80]}")
    control = Control(float(u[0]), float(u[1]))
    if not team:
        return TickRecord(k, control, c, h, n, r)
    d, a = obj.get("d"), obj.get("a", False)
    if type(d) is not int or d < 0 or not isinstance(a, bool):
        raise failure(path, n, f"malformed team tick line (d: the driven robot, a: autopilot): "
                             f"{text.strip()[:80]}")
    return TickRecord(k, control, c, h, n, r, driven=d, autopilot=a)


def _state_line_ok(obj: dict, team: bool) -> bool:
    """A checkpoint or end line's checksums (and, for a team, its poses) have the right types."""
    if not isinstance(obj.get("checksum"), str) or not isinstance(obj.get("readings_checksum", ""), str):
        return False
    if "estimates" in obj and not _digests_ok(obj["estimates"]):
        return False
    if "values" in obj and not _values_ok(obj["values"]):
        return False
    if "notes" in obj and not (isinstance(obj["notes"], dict)
                               and all(isinstance(v, str) for v in obj["notes"].values())):
        return False
    return not team or (isinstance(obj.get("poses"), list)
                        and all(isinstance(p, list) and len(p) == 3 and all(is_number(x) for x in p)
                                for p in obj["poses"]))


def _digests_ok(d: Any) -> bool:
    return isinstance(d, dict) and len(d) <= MAX_SENSORS \
        and all(v is None or isinstance(v, str) for v in d.values())


def _values_ok(d: Any) -> bool:
    """An estimates or end line's ``values``: {NAME: nine numbers per robot, or null}."""
    return isinstance(d, dict) and len(d) <= MAX_SENSORS and all(
        v is None or (isinstance(v, list) and 0 < len(v) <= VALUES_PER_ROBOT * MAX_ROBOTS
                      and len(v) % VALUES_PER_ROBOT == 0 and all(is_number(x) for x in v))
        for v in d.values())


def _settings_ok(obj: dict) -> bool:
    f = obj.get("filters")
    return isinstance(f, dict) and len(f) <= MAX_SENSORS and all(
        isinstance(v, dict) and (v.get("params") is None or isinstance(v["params"], dict))
        and isinstance(v.get("failed", ""), str) for v in f.values())


def _read_file(path: Path) -> tuple[dict[str, Any], list[Any], dict[int, dict[str, Any]],
                                    dict[str, Any] | None, list[str], FileParts]:
    """(header, ticks, checkpoints, end, warnings, the other parts) of a recording of either
    kind (json only; nothing is executed). A truncated or unreadable *last* line is skipped
    with a warning; anything else malformed raises :class:`RecordingError` naming the file
    and line. A signed file's signature lines are checked with the key in
    :data:`KEY_VARIABLE` (a difference raises RecordingError)."""
    lines = list(_iter_lines(path))
    if not lines:
        raise RecordingError(f"{path}: empty file, not a recording")
    header: dict[str, Any] | None = None
    team = False
    ticks: list[Any] = []
    checkpoints: dict[int, dict[str, Any]] = {}
    end = None
    notes: list[str] = []
    parts = FileParts()
    key = recording_key()
    signer: Signer | None = None
    signed_to = 0  # the last line a matching signature covers
    last = len(lines)
    for n, text, complete in lines:
        if not text.strip():
            if signer:
                signer.add(text)
            continue
        obj = _decode(path, n, text)
        if obj is None or not complete:
            if n == last and n > 1:
                notes.append(f"{path}:{n}: incomplete last line skipped (the program was "
                             "probably stopped while writing)")
                break
            if n == 1:
                raise failure(path, 1, "corrupted header (not one complete JSON object)")
            raise failure(path, n, "not valid JSON")
        if n == 1:
            _check_header(path, obj)
            header = obj
            team = is_team_header(obj)
            if key is not None and obj.get("signed"):
                signer = Signer(key)
                signer.add(text)
            continue
        if header is None:  # line 1 was blank: every later line needs the header
            raise failure(path, 1, "corrupted header (missing)")
        kind = obj.get("type") if isinstance(obj, dict) else None
        if kind == "signature" and header.get("signed"):
            mac = obj.get("hmac")
            if signer is not None:
                if not (isinstance(mac, str) and hmac.compare_digest(mac, signer.hexdigest())):
                    # reported by the replay after its own checks (which name the field)
                    parts.signature_error = (
                        f"{path}:{n}: signature does not match: the lines before it were changed "
                        f"after they were written, or signed with another key than {KEY_VARIABLE}'s")
                    signer = None
                    continue
                signed_to = n
                signer.add(text)
            continue
        if signer:
            signer.add(text)
        if end is not None:
            raise failure(path, n, "data after the end line")
        if kind == "tick":
            ticks.append(_tick_line(path, n, text, obj, ticks[-1].tick + 1 if ticks else 1, team))
        elif kind == "checkpoint":
            if type(obj.get("k")) is not int or not _state_line_ok(obj, team):
                raise failure(path, n, "malformed checkpoint line")
            if header["version"] >= 3 and (not ticks or obj["k"] != ticks[-1].tick):
                raise failure(path, n, f"checkpoint of tick {obj['k']} after the line of tick "
                                     f"{ticks[-1].tick if ticks else 0}")
            if obj["k"] in checkpoints or obj["k"] in parts.estimates:
                # the recorder writes a tick's checkpoint once, before its estimates line
                before = "another checkpoint" if obj["k"] in checkpoints else "its estimates line"
                raise failure(path, n, f"checkpoint of tick {obj['k']} out of order (after {before} "
                                     "of that tick): was the file edited?")
            checkpoints[obj["k"]] = obj
        elif kind == "estimates" and header["version"] >= 3:
            if type(obj.get("k")) is not int or not _digests_ok(obj.get("digests")) \
                    or not _state_line_ok({"checksum": "", **obj, "estimates": {}}, False):
                raise failure(path, n, "malformed estimates line")
            if not ticks or obj["k"] != ticks[-1].tick or obj["k"] in parts.estimates:
                raise failure(path, n, f"estimates of tick {obj['k']} after the line of tick "
                                     f"{ticks[-1].tick if ticks else 0}")
            parts.estimates[obj["k"]] = {**obj, "line": n}
        elif kind == "filters" and header["version"] >= 3 \
                and parts.settings is None and not ticks:
            if not _settings_ok(obj):
                raise failure(path, n, "malformed filters line")
            parts.settings, parts.settings_line = obj["filters"], n
        elif kind == "end":
            if not _state_line_ok(obj, team):
                raise failure(path, n, "malformed end line")
            end = obj
        else:
            raise failure(path, n, f"unknown line type {short_text(kind)}")
    if header is None:
        raise failure(path, 1, "corrupted header (missing)")
    if header["version"] >= 3:
        _check_every_checkpoint(path, header, ticks, checkpoints, parts, end is not None)
    if end is None:
        notes.append(f"{path}: no end line (the run was interrupted); replaying the "
                     f"{len(ticks)} complete ticks")
    parts.signature = "signature does not match" if parts.signature_error else \
        _signature_status(header, key, signed_to, last_line(lines))
    return header, ticks, checkpoints, end, notes, parts


def _check_every_checkpoint(path: Path, header: dict[str, Any], ticks: list[Any],
                            checkpoints: dict[int, Any], parts: FileParts, ended: bool) -> None:
    """A version 3 file holds a checkpoint (and, with a filters line, an estimates line)
    after every ``checkpoint_every``-th tick: one removed or moved is an edit. A killed
    run's file may lack the last one."""
    every = header.get("checkpoint_every")
    if type(every) is not int or every < 1:
        raise failure(path, 1, f"corrupted header: checkpoint_every = {short_text(every)}")
    last = ticks[-1].tick if ticks else 0
    due = set(range(every, last + 1, every))
    for what, got in [("checkpoint", set(checkpoints)),
                      *([("estimates", set(parts.estimates))] if parts.settings is not None else [])]:
        missing = sorted(due - got - (set() if ended else {max(due, default=0)}))
        if missing:
            raise failure(path, 1, f"no {what} line after tick {missing[0]} (one every "
                                 f"{every} ticks): was the file edited?")


def last_line(lines: list[tuple[int, str, bool]]) -> int:
    """The number of the last line that is not blank."""
    return max((n for n, text, _ in lines if text.strip()), default=0)


def _signature_status(header: dict[str, Any], key: bytes | None, signed_to: int, last: int) -> str:
    """What the signature proves, in words (docs/replay.md, "Signed recordings")."""
    if not header.get("signed"):
        return "not signed"
    if key is None:
        return f"signed (not checked: {KEY_VARIABLE} is not set)"
    if signed_to == last:
        return "signed and verified"
    if signed_to:
        return f"signed and verified up to line {signed_to} (the lines after it are not signed)"
    return "signed, but no signature line (the run was interrupted before the first)"


def _check_dt(path: Path, header: dict[str, Any], dt: float) -> None:
    if not math.isclose(dt, float(header["dt"]), rel_tol=0, abs_tol=0):
        raise failure(path, 1, f"corrupted header: dt {header['dt']} but the scenario says {dt}")


def _slip_model(path: Path, header: Mapping[str, Any]) -> str:
    """The header's "slip_model" (the motion noise model); "legacy" for a file made before it."""
    model = header.get("slip_model", RECORDED_BEFORE_SLIP_MODEL)
    if model not in SLIP_MODELS:
        raise failure(path, 1, f"corrupted header: slip_model = {model!r} (expected "
                             f"{' or '.join(repr(m) for m in SLIP_MODELS)})")
    return str(model)


def load_recording(path) -> Recording:
    """Read a recording of any number of robots (json only; nothing is executed): a single
    robot's file as a team of one, a team's file as its team.

    A truncated or unreadable *last* line (a killed program) is skipped with a warning in
    ``Recording.warnings``; anything else malformed raises :class:`RecordingError` naming
    the file and line (a robot index out of range included).
    """
    path = Path(path)
    header, ticks, checkpoints, end, notes, parts = _read_file(path)
    file = f"{path} (scenario {header.get('scenario_source', header['scenario_name'])})"
    slip = _slip_model(path, header)
    team: TeamScenario
    if not is_team_header(header):
        source = header.get("scenario_source")
        grid = recorded_map(path, header)
        if grid is not None:
            src = source if isinstance(source, str) else None
            note = disk_map_note(grid, str(header["map"]["file"]), src)
            if note is not None:
                notes.append(f"{path}: {note}")
            if note is not None or (scenario_folder(src) is None
                                    and not Path(str(header["map"]["file"])).is_absolute()):
                why = "it differs from the map file" if note and "differs" in note else \
                    "the map file cannot be read" if note else "a user's map file is not looked for"
                parts.map_unverified = (f"the stored map (its own sha256 is all it can be checked "
                                        f"against, and an edit can recompute that; {why})")
        scenario = rebuild_scenario(header["scenario_toml"], file, header["scenario_name"],
                                    source, map_grid=grid)
        _check_dt(path, header, scenario.dt)
        team = team_of_one(replace(scenario_with_slip(scenario, slip), seed=int(header["seed"])))
        return Recording(path, header, team, ticks, checkpoints, end, notes, parts)
    team = rebuild_team_scenario(header["scenario_toml"], file, header["scenario_name"])
    _check_dt(path, header, team.dt)
    team = team_with_slip(team, slip)
    n = len(team.robots)
    for rec in ticks:
        try:
            if rec.driven >= n:
                raise ValueError(f"driven robot {rec.driven}: expected an index from 0 to {n - 1}")
            for cmd in rec.commands:
                validate_command(cmd, n)
        except ValueError as exc:
            raise failure(path, rec.line, str(exc)) from None
    for k, obj in [*checkpoints.items(), (-1, end or {"poses": [None] * n})]:
        if len(obj["poses"]) != n:
            raise failure(path, 1, f"corrupted {'end' if k < 0 else f'checkpoint {k}'}: "
                                 f"{len(obj['poses'])} poses for {n} robots")
    team = replace(team, seed=int(header["seed"]))
    return Recording(path, header, team, ticks, checkpoints, end, notes, parts)

