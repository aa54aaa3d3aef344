"""Recordings: every run written as it goes, in JSON Lines, so it can be replayed bit for bit.

One JSON object per line (format described in docs/replay.md):

- line 1, the header: ``{"type": "header", "format": "beacon-sim-recording", "version": 1,
  "program_version", "created", "scenario_name", "scenario_source", "scenario_toml" (the
  full text of the scenario file), "seed", "dt", "filters" (specs), "params" ({NAME: {KEY:
  VALUE}}, the ``--set`` overrides), "checkpoint_every" (ticks)}``;
- one line per tick: ``{"type": "tick", "k": tick, "u": [v, omega], "h": "8 hex digits"}``
  plus ``"c": [commands]`` when the user gave commands on that tick (user_commands.py);
  ``h`` is the start of the truth checksum after the tick, so a replay names the first tick
  that differs;
- every ``checkpoint_every`` ticks (one simulated second): ``{"type": "checkpoint", "k",
  "time", "pose": [x, y, theta], "checksum"}``;
- last: ``{"type": "end", "ticks", "pose", "checksum"}``.

The recorder re-simulates alongside the caller (a shadow :class:`Simulation` from the same
scenario and seed, given the same controls and commands), so the file carries its own
checksums whatever the caller passes. Lines are flushed at least every half second of
simulated or wall time: a killed program leaves a file that replays to within a second of
the kill. Reading never executes code: ``json`` only.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import time
import tomllib
import warnings
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from beacon_sim import __version__
from beacon_sim.core.scenario import Scenario, ScenarioError, parse_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.core.types import Control
from beacon_sim.user_commands import apply_commands, validate_command

FORMAT_NAME = "beacon-sim-recording"
FORMAT_VERSION = 1
#: Flush the file when this much simulated or wall time [s] has passed since the last flush.
FLUSH_EVERY_S = 0.5
RECORDINGS_DIR = "recordings"


class RecordingError(ValueError):
    """A recording file that cannot be read or replayed. The message is one line."""


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


def _scenario_text(scenario: Scenario) -> str:
    try:
        return Path(scenario.source).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise RecordingError(f"{scenario.source}: cannot read the scenario file to record it: {exc}") \
            from None


def _dumps(obj: Mapping[str, Any]) -> str:
    # Python's float repr round-trips exactly, so poses and controls come back bit for bit.
    return json.dumps(obj, separators=(",", ":"), allow_nan=True)


class Recorder:
    """Writes one run to ``path`` as it goes.

    Parameters
    ----------
    path : str or Path
        The ``.jsonl`` file to create (its folder is created too).
    scenario : Scenario
        Loaded from a TOML file; its text is stored so replay rebuilds it exactly.
    seed : int
    filters : list of str
        The filter specs of the run.
    params : dict
        ``{NAME: {KEY: VALUE}}`` parameter overrides (``--set``) of the run.

    Call :meth:`record_tick` once per tick *before* the caller's ``sim.step`` of that tick,
    with the control and the user commands applied on that tick; then :meth:`close`.
    """

    def __init__(self, path, scenario: Scenario, seed: int, filters: list[str],
                 params: dict | None = None, *, checkpoint_every: int | None = None):
        self.path = Path(path)
        self.scenario = scenario
        self.seed = int(seed)
        text = _scenario_text(scenario)
        rebuilt = _rebuild(text, scenario.source, scenario.name)
        if replace(rebuilt, seed=scenario.seed, duration=scenario.duration) != scenario:
            warnings.warn(f"{scenario.source}: the scenario was changed after loading; the "
                          "recording stores the file as it is on disk", stacklevel=2)
        self.checkpoint_every = checkpoint_every or max(1, round(1.0 / scenario.dt))
        self.shadow = Simulation(rebuilt, self.seed)
        self.ticks = 0
        self._expected_tick: int | None = None
        self._warned_gap = False
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = self.path.open("w", encoding="utf-8", newline="\n")
        header = {
            "type": "header", "format": FORMAT_NAME, "version": FORMAT_VERSION,
            "program_version": __version__,
            "created": _dt.datetime.now().astimezone().isoformat(timespec="seconds"),
            "scenario_name": scenario.name, "scenario_source": str(scenario.source),
            "scenario_toml": text, "seed": self.seed, "dt": scenario.dt,
            "filters": list(filters), "params": {k: dict(v) for k, v in (params or {}).items()},
            "checkpoint_every": self.checkpoint_every,
        }
        self._file.write(_dumps(header) + "\n")
        self._file.flush()
        self._last_flush_wall = time.monotonic()
        self._last_flush_tick = 0

    @property
    def truth_checksum(self) -> str:
        """Checksum of the true trajectory recorded so far (equals the caller's
        ``sim.truth_checksum`` after the same ticks: a cheap consistency check)."""
        return self.shadow.truth_checksum

    def record_tick(self, tick: int, control: Control | None, commands: list[dict] | None = None) -> None:
        """Record the control [m/s, rad/s] and the user commands of one tick.

        ``control`` None means "the scenario's driver decides"; the driver's command is
        recorded. ``tick`` should count up by one per call (a gap is warned about once).
        """
        if self._file is None:
            raise RecordingError(f"{self.path}: recorder already closed")
        commands = [dict(c) for c in (commands or [])]
        for c in commands:
            validate_command(c)
        if self._expected_tick is not None and tick != self._expected_tick and not self._warned_gap:
            warnings.warn(f"{self.path}: tick {tick} recorded after {self._expected_tick - 1}; "
                          "ticks should be recorded one by one", stacklevel=2)
            self._warned_gap = True
        self._expected_tick = tick + 1
        apply_commands(commands, self.shadow, {}, self.shadow.scenario)
        step = self.shadow.step(control)
        self.ticks += 1
        line: dict[str, Any] = {"type": "tick", "k": step.tick,
                                "u": [step.control.v, step.control.omega],
                                "h": self.shadow.truth_checksum[:8]}
        if commands:
            line["c"] = commands
        self._file.write(_dumps(line) + "\n")
        if step.tick % self.checkpoint_every == 0:
            self._file.write(_dumps(self._state_line("checkpoint")) + "\n")
        now = time.monotonic()
        if (now - self._last_flush_wall >= FLUSH_EVERY_S
                or (step.tick - self._last_flush_tick) * self.scenario.dt >= FLUSH_EVERY_S):
            self._file.flush()
            self._last_flush_wall = now
            self._last_flush_tick = step.tick

    def _state_line(self, kind: str) -> dict[str, Any]:
        sim = self.shadow
        out: dict[str, Any] = {"type": kind}
        if kind == "end":
            out["ticks"] = sim.tick
        else:
            out["k"] = sim.tick
            out["time"] = sim.time
        out["pose"] = [float(v) for v in sim.pose]
        out["checksum"] = sim.truth_checksum
        return out

    def close(self) -> None:
        """Write the end line (final truth checksum) and close the file. Idempotent."""
        if self._file is None:
            return
        self._file.write(_dumps(self._state_line("end")) + "\n")
        self._file.close()
        self._file = None

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


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


def _rebuild(text: str, file: str, name: str) -> Scenario:
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
    if version != FORMAT_VERSION:
        raise _fail(path, 1, f"recording format version {version!r} is not supported by "
                             f"beacon-sim {__version__} (it reads version {FORMAT_VERSION})")
    need = {"scenario_toml": str, "scenario_name": str, "seed": int, "dt": (int, float),
            "filters": list, "params": dict}
    for key, typ in need.items():
        if not isinstance(header.get(key), typ) or isinstance(header.get(key), bool):
            raise _fail(path, 1, f"corrupted header: {key} = {header.get(key)!r}")


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
            ticks.append(TickRecord(k, Control(float(u[0]), float(u[1])), c, obj.get("h"), n))
        elif kind == "checkpoint":
            if not isinstance(obj.get("k"), int) or not isinstance(obj.get("checksum"), str):
                raise _fail(path, n, "malformed checkpoint line")
            checkpoints[obj["k"]] = obj
        elif kind == "end":
            if not isinstance(obj.get("checksum"), str):
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
    scenario = _rebuild(header["scenario_toml"], file, header["scenario_name"])
    if not math.isclose(scenario.dt, float(header["dt"]), rel_tol=0, abs_tol=0):
        raise _fail(path, 1, f"corrupted header: dt {header['dt']} but the scenario says {scenario.dt}")
    scenario = replace(scenario, seed=int(header["seed"]))
    return Recording(path, header, scenario, ticks, checkpoints, end, notes)
