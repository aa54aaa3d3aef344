"""Recordings: every run written as it goes, in JSON Lines, so it can be replayed bit for bit.

One JSON object per line (format described in docs/replay.md):

- line 1, the header: ``{"type": "header", "format": "beacon-sim-recording", "version": 4,
  "program_version", "created", "scenario_name", "scenario_source" (a shipped scenario's
  name, or a user's file name without its folder: :func:`scenario_label`), "scenario_toml"
  (the full text of the scenario file), "scenario_sha256" (its SHA-256, 64 hex digits),
  "seed", "dt", "filters" (specs), "params" ({NAME: {KEY: VALUE}}, the ``--set``
  overrides), "checkpoint_every" (ticks), "signed" (true when an HMAC signs the file),
  "maths" (16 hex digits: the maths fingerprint of the machine that made it,
  :func:`beacon_sim.core.maths_fingerprint.maths_fingerprint`), "maths_description" (the
  same for people)}``, plus the keys of :data:`MODEL_KEYS`;
- line 2 (version 3, when the recorder saw the filters): ``{"type": "filters", "filters":
  {NAME: {"params": {KEY: VALUE} | null, "failed": why (absent when built)}}}``, the
  effective parameters of every built filter (its merged ``params``, defaults included);
- one line per tick: ``{"type": "tick", "k": tick, "u": [v, omega], "h": "8 hex digits",
  "r": "8 hex digits"}`` (truth and readings checksums)
  plus ``"c": [commands]`` when the user gave commands on that tick (:data:`COMMAND_KINDS`;
  their effect is in beacon_sim/runs/user_commands.py);
  ``h`` is the start of the truth checksum after the tick, so a replay names the first tick
  that differs;
- every ``checkpoint_every`` ticks (one simulated second): ``{"type": "checkpoint", "k",
  "time", "pose": [x, y, theta], "checksum", "readings_checksum"}``;
- version 3, after the estimates of every checkpoint's tick: ``{"type": "estimates", "k",
  "digests": {NAME: 64 hex digits | null}}`` (:class:`EstimateDigests`; null: not compared,
  e.g. the filter was reloaded live), and ``"notes": {NAME: why}`` when a filter was
  switched off or reloaded live; version 4 adds ``"values": {NAME: [x, y, theta, Pxx, Pxy,
  Pxtheta, Pyy, Pytheta, Pthetatheta, ...] | null}``, the estimate of that tick itself
  (:func:`estimate_values`: nine floats per robot), so a replay on other maths can compare
  it within a tolerance;
- last: ``{"type": "end", "ticks", "pose", "checksum", "readings_checksum"}`` (version 3
  adds ``"estimates"`` and ``"notes"`` as on an estimates line, for the last tick; version
  4 ``"values"`` too);
- signed files (``BEACON_SIM_RECORDING_KEY`` set when recording): after each checkpoint's
  estimates and after the end line, ``{"type": "signature", "hmac": 64 hex digits}``, the
  HMAC-SHA256 of every byte of the file before that line (:class:`Signer`).

Version 1 files (no readings checksums, no scenario checksum), version 2 files (no
filter settings, no estimates) and version 3 files (no maths fingerprint, no estimate
values) are still read; a replay says what they cover.

The header's ``"slip_model"`` (``"scaled"``, slip scaling with the command) names
the motion noise the run was made with; a file without it was made before and replays with
``"legacy"`` (noise at standstill). The tick's ``u`` is the command as given, also on a
tick the bumper stopped (the filters were told v = 0).

One format over N robots (a single robot is a team of one). A single robot's
file is the format above, unchanged since version 1; a team's (several robots,
docs/multi-robot.md) is the same format with ``"kind": "team"`` in the header (and
``"robots"``: their names); the scenario is the team file, ``filters`` team filter specs.
Its tick lines add ``"d"`` (the index of the driven robot) and ``"a": true`` when the driven
robot's own driver chose ``u`` (autopilot), and its commands name the robot they act on
(:data:`TEAM_COMMAND_KINDS`); checkpoint and end lines hold ``"poses"`` (one ``[x, y,
theta]`` per robot) instead of ``"pose"``. The checksums are the team's
(:class:`beacon_sim.core.team.TeamSimulation` ``truth_checksum``, and
``beacon_sim.runs.recorder.TeamReadingsHash`` over every robot's readings); a single-robot
filter run on every robot (``independent:F``) is stored as one team filter
(``hosting/team_runner.StackedTrack``). :func:`load_recording` reads both kinds into one
:class:`Recording` (a single robot's file as a team of one).

This module is the format: reading a file (:func:`load_recording`) and the pieces the writer
shares (:class:`beacon_sim.runs.recorder.Recorder` writes a file of either kind as a run goes). Reading
never executes code: ``json`` only.
"""

from __future__ import annotations

import base64
import datetime as _dt
import hashlib
import hmac
import io
import json
import math
import os
import zlib
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from beacon_sim.core.files import open_user_file, read_user_text
from beacon_sim.core.motion import SLIP_MODELS
from beacon_sim.core.occupancy import MAX_CELLS, MapError, OccupancyGrid, load_map
from beacon_sim.core.resources import scenario_dir
from beacon_sim.core.scenario import (
    MAX_COORD,
    MAX_SCENARIO_BYTES,
    MAX_SENSORS,
    MAX_SPEED,
    Scenario,
    ScenarioError,
    check_document,
    env_limit,
    parse_scenario,
    parse_toml_text,
)
from beacon_sim.core.simulation import RECORDED_BEFORE_SLIP_MODEL, scenario_with_slip
from beacon_sim.core.team import team_with_slip
from beacon_sim.core.team_scenario import (
    MAX_ROBOTS,
    TeamScenario,
    is_team_document,
    parse_team_scenario,
    team_of_one,
)
from beacon_sim.core.types import Control
from beacon_sim.errors import BeaconSimError
from beacon_sim.hosting.team_runner import TeamRunner
from beacon_sim.version import __version__

FORMAT_NAME = "beacon-sim-recording"
FORMAT_VERSION = 4
#: Versions this program reads. Version 1 files carry checksums of the truth only; version 2
#: adds the readings (``r`` per tick, ``readings_checksum``) and the scenario text
#: (``scenario_sha256`` in the header, 16 hex digits); version 3 the effective filter
#: parameters (the filters line), digests of the estimates (estimates lines), the full
#: SHA-256 of the scenario and the optional HMAC signature; version 4 (truth and
#: readings made with the portable maths, the same bits on every machine) the maths
#: fingerprint of the machine that made it and the estimates' values at every estimates
#: line, so that a replay on other maths compares them within a tolerance.
READ_VERSIONS = (1, 2, 3, 4)
#: The header keys a version 3 or 4 writer puts in a header ("maths" and
#: "maths_description": version 4).
HEADER_KEYS = frozenset({
    "type", "format", "version", "program_version", "created", "scenario_name",
    "scenario_source", "scenario_toml", "scenario_sha256", "seed", "dt", "filters", "params",
    "checkpoint_every", "signed", "kind", "robots", "maths", "maths_description"})
#: Longest ``maths_description`` [characters].
MAX_DESCRIPTION_CHARS = 200
#: Numbers an estimate of one robot takes on an estimates line: the mean (3) and the
#: covariance's upper triangle (6), :func:`estimate_values`.
VALUES_PER_ROBOT = 9
#: Header keys that shape the truth beyond the scenario text, the seed and dt (e.g. a motion
#: model's version): the one place a new such key is declared. A version 3 header holding a
#: key in neither HEADER_KEYS nor MODEL_KEYS is refused (an edit, or a newer writer); the
#: replay checks the truth these keys shape through the truth and readings checksums.
MODEL_KEYS: tuple[str, ...] = ("slip_model",  # the motion noise model
                                "map")  # the occupancy grid a world.map names
#: The environment variable holding the key of the optional HMAC signature.
KEY_VARIABLE = "BEACON_SIM_RECORDING_KEY"

# Caps on a recording, checked before it is parsed (docs/replay.md, "Caps"); each can be
# raised with the environment variable BEACON_SIM_MAX_<NAME>.
#: Largest recording file [bytes] (a 10^6-tick run writes about 120 MB).
MAX_RECORDING_BYTES = 2**30
#: Longest line [characters] (the header holds the scenario, at most 2 MiB).
MAX_LINE_CHARS = 16 * 2**20
#: Most user commands on one tick (the window queues a few per frame).
MAX_COMMANDS = 100
#: Largest recorded turn rate [rad/s]: a circle driver's speed / radius at most reaches
#: 100 m/s / 1 mm (speeds are at most MAX_SPEED).
MAX_RECORDED_TURN = 1e5
#: Longest filter name in a toggle command [characters].
MAX_NAME_CHARS = 200
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


def _short(x: Any) -> str:
    text = repr(x)
    return text if len(text) <= 60 else text[:57] + "..."


def check_pose(pose: Any) -> None:
    """Raise ValueError unless ``pose`` is ``[x, y, theta]``: three finite numbers within
    MAX_COORD [m, m, rad]."""
    if not (isinstance(pose, list | tuple) and len(pose) == 3
            and all(_number(x) and _finite_in(x, MAX_COORD) for x in pose)):
        raise ValueError(f"kidnap pose {_short(pose)}: expected [x, y, theta], three finite "
                         f"numbers within +-{MAX_COORD:g} (metres, radians)")


def check_toggle(cmd: Mapping) -> None:
    name = cmd.get("filter")
    if not isinstance(name, str) or len(name) > MAX_NAME_CHARS:
        raise ValueError(f"toggle of {_short(name)}: expected a filter name (a string of at "
                         f"most {MAX_NAME_CHARS} characters)")


#: The header's ``kind`` of a team's recording (absent: one robot, a team of one).
TEAM_KIND = "team"
#: The user commands a team's recording may hold (applied by runs/user_commands.py):
#: ``{"kind": "kidnap", "robot": i}`` (K: a random pose) or with ``"pose": [x, y, theta]``
#: (click), robot i in team order; ``{"kind": "reset"}`` (R: every filter back to the
#: initial beliefs); ``{"kind": "toggle", "filter": NAME}`` (display). A single robot's
#: file holds :data:`COMMAND_KINDS` (no robot index: its one robot).
TEAM_COMMAND_KINDS = ("kidnap", "reset", "toggle")


def validate_command(cmd: Mapping, n_robots: int | None = None) -> None:
    """Raise ValueError for a command this version does not know, or one whose values are
    not what it takes (a kidnap pose of three finite numbers, a toggle's filter name).

    ``n_robots`` None: a single robot's command (:data:`COMMAND_KINDS`); a number: a team's
    (:data:`TEAM_COMMAND_KINDS`), whose kidnap names a robot index below ``n_robots`` (0: a
    team whose size is not known yet, any index)."""
    kind = cmd.get("kind")
    team = n_robots is not None
    kinds = TEAM_COMMAND_KINDS if team else COMMAND_KINDS
    if kind not in kinds:
        raise ValueError(f"unknown {'team' if team else 'user'} command {_short(kind)}; "
                         f"expected one of {kinds}")
    if kind == "kidnap" and team:
        robot = cmd.get("robot")
        if not isinstance(robot, int) or isinstance(robot, bool) or robot < 0 \
                or (n_robots is not None and n_robots > 0 and robot >= n_robots):
            raise ValueError(f"kidnap of robot {_short(robot)}: expected a robot index"
                             + (f" from 0 to {n_robots - 1}" if n_robots else ""))
    if kind == "kidnap" and "pose" in cmd:
        check_pose(cmd["pose"])
    if kind == "toggle":
        check_toggle(cmd)


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


def open_exclusive(path: Path) -> tuple[TextIO, Path]:
    """Create ``path`` for writing, exclusively (``O_EXCL``: never a file another session
    has just created); when the name is taken, ``<stem>-2.jsonl``, ``-3``, ... instead.
    Returns the open file and its path. Its folder is created; one that cannot be (a file, a
    dangling symlink or a symlink loop in its place) is a RecordingError saying so."""
    folder = path.parent
    if os.path.lexists(folder) and not folder.is_dir():
        what = ("a symlink loop or a symlink to nothing" if folder.is_symlink() and not folder.exists()
                else "a file")
        raise RecordingError(f"{folder}: cannot record there: it is {what}, not a folder (move it "
                             f"away, or pass --no-record)")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RecordingError(f"{folder}: cannot create the recordings folder: "
                             f"{exc.strerror or exc}") from None
    base = path.with_suffix("")
    for n in range(1, 10_000):
        candidate = path if n == 1 else Path(f"{base}-{n}{path.suffix}")
        try:
            return candidate.open("x", encoding="utf-8", newline="\n"), candidate
        except FileExistsError:
            continue
        except OSError as exc:
            raise RecordingError(f"{candidate}: cannot record there: {exc.strerror or exc}") from None
    raise RecordingError(f"{path}: 10,000 recordings of that name already exist")


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


def text_checksum(text: str, version: int = FORMAT_VERSION) -> str:
    """SHA-256 of a scenario's text as a header of that version stores it: 64 hex digits
    (version 3), the first 16 (version 2)."""
    digest = hashlib.sha256(text.encode("utf-8")).hexdigest()
    return digest if version >= 3 else digest[:16]


def recording_key() -> bytes | None:
    """The HMAC key from :data:`KEY_VARIABLE` (None when unset or empty)."""
    key = os.environ.get(KEY_VARIABLE, "")
    return key.encode("utf-8") if key else None


class Signer:
    """A running HMAC-SHA256 over the bytes of a recording, line by line (the writer's and
    the reader's: the same bytes give the same ``hexdigest`` before each signature line)."""

    def __init__(self, key: bytes):
        self._mac = hmac.new(key, digestmod=hashlib.sha256)

    def add(self, line: str) -> None:
        """One line of the file as written (its newline included)."""
        self._mac.update(line.encode("utf-8"))

    def hexdigest(self) -> str:
        return self._mac.hexdigest()


def estimate_bytes(tick: int, mean: np.ndarray, cov: np.ndarray) -> bytes:
    """What an estimate adds to its filter's digest: the tick (int64) then the mean and the
    covariance as float64, little-endian, C order (a team filter's: every robot's)."""
    return (np.int64(tick).astype("<i8").tobytes()
            + np.ascontiguousarray(mean, dtype="<f8").tobytes()
            + np.ascontiguousarray(cov, dtype="<f8").tobytes())


def estimate_values(mean: np.ndarray, cov: np.ndarray) -> list[float]:
    """An estimate as an estimates line stores it (version 4): per robot, the mean ``[x, y,
    theta]`` [m, m, rad] then the covariance's upper triangle ``[Pxx, Pxy, Pxtheta, Pyy,
    Pytheta, Pthetatheta]`` [m^2, m^2, m rad, m^2, m rad, rad^2], as Python floats (written
    with repr: they read back bit for bit). ``mean`` (3,) or (N, 3), ``cov`` (3, 3) or (N, 3, 3)."""
    m = np.asarray(mean, dtype=float).reshape(-1, 3)
    c = np.asarray(cov, dtype=float).reshape(-1, 3, 3)
    rows, cols = np.triu_indices(3)
    return [float(v) for v in np.concatenate([m, c[:, rows, cols]], axis=1).ravel()]


class EstimateDigests:
    """A running SHA-256 per filter over the estimates it gave (:func:`estimate_bytes`), tick
    by tick: what a version 3 recording stores at its checkpoints and at its end, and what a
    replay recomputes; and each filter's latest estimate, whose :func:`estimate_values` a
    version 4 file stores beside the digests. ``update`` reads a runner's tracks (``ticks``,
    ``means``, ``covs``) once per tick, after the filters were fed."""

    def __init__(self) -> None:
        self._hash: dict[str, Any] = {}
        self._latest: dict[str, tuple[int, np.ndarray, np.ndarray]] = {}

    def update(self, tick: int, tracks: Mapping[str, Any]) -> None:
        for name, track in tracks.items():
            h = self._hash.get(name)
            if h is None:
                h = self._hash[name] = hashlib.sha256()
            if track.ticks and track.ticks[-1] == tick:
                mean, cov = track.means[-1], track.covs[-1]
                h.update(estimate_bytes(tick, mean, cov))
                self._latest[name] = (tick, mean, cov)

    def digest(self, name: str) -> str:
        """The filter's digest so far (the digest of nothing before its first estimate)."""
        return (self._hash.get(name) or hashlib.sha256()).hexdigest()

    def values(self, name: str, tick: int) -> list[float] | None:
        """The filter's estimate of ``tick`` as :func:`estimate_values` (None: it gave none
        on that tick, e.g. it was switched off)."""
        latest = self._latest.get(name)
        if latest is None or latest[0] != tick:
            return None
        return estimate_values(latest[1], latest[2])


def recorded_tracks(runner: Any) -> dict[str, Any]:
    """The tracks a recording stores, by filter name, in the run's order: a
    :class:`~beacon_sim.hosting.team_runner.TeamRunner` on a team of one, its one robot's
    tracks (a single robot's file); on a team, ``team_tracks()``: each team filter's joint
    track, each single-robot filter's copies as one ``StackedTrack`` (every robot's estimate,
    robot by robot: the former joint ``IndependentTeam``'s). Anything else with ``tracks``
    (a FilterRunner or a JointRunner): those."""
    if not isinstance(runner, TeamRunner):
        return dict(runner.tracks)
    if runner.team.solo:
        return dict(runner.members[0].tracks)
    return runner.team_tracks()


def effective_params(flt: Any) -> dict[str, Any] | None:
    """A built filter's effective parameters (its merged ``params``, defaults included; an
    independent team's member filters' too) as JSON values, or None when it has none."""
    params = getattr(flt, "params", None)
    if not isinstance(params, Mapping):
        return None
    out: dict[str, Any] = {str(k): v for k, v in params.items()}
    members = getattr(flt, "filters", None)
    if isinstance(members, list) and members and all(hasattr(m, "params") for m in members):
        out = {**out, "members": [effective_params(m) for m in members]}
    return json.loads(json.dumps(out, default=_jsonable, allow_nan=True))


def _jsonable(x: Any) -> Any:
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, set | frozenset | tuple):
        return list(x)
    return repr(x)


def dumps(obj: Mapping[str, Any]) -> str:
    # Python's float repr round-trips exactly, so poses and controls come back bit for bit.
    return json.dumps(obj, separators=(",", ":"), allow_nan=True)




# --------------------------------------------------------------------------------------------
# Reading


@dataclass
class TickRecord:
    """One recorded tick: its number, control, user commands and short truth checksum; on a
    team's file also the driven robot (index in team order) and whether its own driver chose
    ``control`` (autopilot: a replay lets the driver choose again, so the driver's state,
    e.g. its next waypoint, follows as it did live). A single robot's: robot 0, never
    autopilot (its file holds the command the driver chose)."""

    tick: int
    control: Control
    commands: list[dict]
    short_checksum: str | None = None
    line: int = 0
    readings_checksum: str | None = None  # version 2: first 8 hex digits of the readings'
    driven: int = 0
    autopilot: bool = False


@dataclass
class FileParts:
    """What a recording file holds besides its ticks (version 3: the filters line, the
    estimates lines; a signed file: how far its signature was checked)."""

    settings: dict[str, dict[str, Any]] | None = None  # the filters line's "filters"
    settings_line: int = 0
    estimates: dict[int, dict[str, Any]] = field(default_factory=dict)  # tick -> line
    signature: str = "not signed"
    signature_error: str | None = None  # a signature line that does not match (names it)
    # why the stored map could not be checked against a map file (None: no stored map, or
    # it is the shipped scenario's map file cell for cell)
    map_unverified: str | None = None


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


def rebuild_scenario(text: str, file: str, name: str, source: str | None = None,
                     map_grid: OccupancyGrid | None = None) -> Scenario:
    """A scenario from its stored text (the same checks and caps as loading the file); a
    map file it names is ``map_grid`` when given (the recorded map), else read from beside
    ``source``, the header's ``scenario_source`` (:func:`scenario_folder`)."""
    base = scenario_folder(source)
    return parse_scenario(parse_toml_text(text, file), file, name=name, base_dir=base,
                          map_grid=map_grid)


# --------------------------------------------------------------------------------------------
# The map in the header (a map world's occupancy grid)


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
        return _fail(path, 1, f"corrupted header: map: {what}")

    if not isinstance(m, dict) or not isinstance(m.get("file"), str):
        raise bad("expected {file, shape, resolution, origin, cells, sha256}")
    shape, res, origin = m.get("shape"), m.get("resolution"), m.get("origin")
    if not (isinstance(shape, list) and len(shape) == 2
            and all(type(v) is int and v > 0 for v in shape) and shape[0] * shape[1] <= MAX_CELLS):
        raise bad(f"shape = {_short(shape)} (expected [rows, cols], at most {MAX_CELLS:,} cells)")
    if not (isinstance(origin, list) and len(origin) == 3 and all(_number(v) for v in origin)
            and _number(res)):
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
        raise _fail(path, 1, "the stored map was edited (its checksum map.sha256 differs): not "
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


def _fail(path: Path, line: int, what: str) -> RecordingError:
    return RecordingError(f"{path}:{line}: {what}")


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
        raise _fail(path, n, "nested too deep to read") from None
    except ValueError as exc:  # an integer over Python's 4,300-digit limit
        raise _fail(path, n, f"not a usable number: {str(exc).splitlines()[0][:80]}") from None
    try:
        check_document(obj, f"{path}:{n}")
    except ScenarioError as exc:
        raise RecordingError(str(exc)) from None
    return obj


def _check_header(path: Path, header: Any) -> None:
    if not isinstance(header, dict) or header.get("type") != "header" \
            or header.get("format") != FORMAT_NAME:
        raise _fail(path, 1, f"not a beacon-sim recording (the first line must be a "
                             f"{FORMAT_NAME!r} header)")
    version = header.get("version")
    if version not in READ_VERSIONS or isinstance(version, bool):
        raise _fail(path, 1, f"recording format version {_short(version)} is not supported by "
                             f"beacon-sim {__version__} (it reads versions "
                             f"{', '.join(map(str, READ_VERSIONS))})")
    kind = header.get("kind")
    if kind is not None and kind != TEAM_KIND:
        raise _fail(path, 1, f"recording kind {str(kind)[:40]!r} is not supported by beacon-sim "
                             f"{__version__} (it reads single-robot and {TEAM_KIND!r} recordings)")
    if kind == TEAM_KIND and version < 2:
        raise _fail(path, 1, "corrupted header: a team recording is version 2 or later")
    if version >= 3:
        unknown = sorted(k for k in header if k not in HEADER_KEYS and k not in MODEL_KEYS)
        if unknown:
            raise _fail(path, 1, f"corrupted header: unknown key {unknown[0][:40]!r} (a version 3 "
                                 "header holds the keys of io/recording.py HEADER_KEYS and MODEL_KEYS)")
    need: dict[str, type | tuple[type, ...]] = {
        "scenario_toml": str, "scenario_name": str, "seed": int, "dt": (int, float),
        "filters": list, "params": dict}
    if version >= 2:
        need["scenario_sha256"] = str
    for key, typ in need.items():
        if not isinstance(header.get(key), typ) or isinstance(header.get(key), bool):
            raise _fail(path, 1, f"corrupted header: {key} = {_short(header.get(key))}")
    if not 0 <= header["seed"] <= 2**63 - 1:
        raise _fail(path, 1, f"corrupted header: seed = {_short(header['seed'])}")
    if not math.isfinite(header["dt"]):
        raise _fail(path, 1, f"corrupted header: dt = {header['dt']!r}")
    if len(header["filters"]) > MAX_SENSORS or len(header["params"]) > MAX_SENSORS:
        raise _fail(path, 1, f"corrupted header: more than {MAX_SENSORS} filters or params")
    if not all(isinstance(f, str) for f in header["filters"]) \
            or not all(isinstance(v, dict) for v in header["params"].values()):
        raise _fail(path, 1, "corrupted header: filters or params")
    if "signed" in header and not isinstance(header["signed"], bool):
        raise _fail(path, 1, f"corrupted header: signed = {_short(header['signed'])}")
    if version >= 4 and not is_fingerprint(header.get("maths")):
        raise _fail(path, 1, f"corrupted header: maths = {_short(header.get('maths'))} (expected "
                             "16 hex digits: the maths fingerprint of the machine that made it)")
    description = header.get("maths_description", "")
    if not isinstance(description, str) or len(description) > MAX_DESCRIPTION_CHARS:
        raise _fail(path, 1, f"corrupted header: maths_description = {_short(description)} "
                             f"(expected a string of at most {MAX_DESCRIPTION_CHARS} characters)")
    if version >= 2 and text_checksum(header["scenario_toml"], version) != header["scenario_sha256"]:
        raise _fail(path, 1, "the stored scenario was edited (its checksum scenario_sha256 "
                             "differs): not the scenario this run was recorded with")


def is_fingerprint(x: Any) -> bool:
    """Whether ``x`` is a maths fingerprint: 16 lower-case hex digits."""
    return isinstance(x, str) and len(x) == 16 and all(ch in "0123456789abcdef" for ch in x)


def _number(x) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool)


def _finite_in(x: float, limit: float) -> bool:
    """Whether the number ``x`` (int or float) is finite and within +-``limit``."""
    try:
        return math.isfinite(float(x)) and abs(x) <= limit
    except OverflowError:  # an integer too large for a float
        return False


def _tick_line(path: Path, n: int, text: str, obj: dict, expected: int,
               team: bool) -> TickRecord:
    """One tick line, checked (``team``: also the driven robot, autopilot, team commands):
    the control finite and within MAX_SPEED [m/s] / MAX_RECORDED_TURN [rad/s], at most
    MAX_COMMANDS user commands, each valid."""
    k, u, c = obj.get("k"), obj.get("u"), obj.get("c", [])
    if not (type(k) is int and isinstance(u, list) and len(u) == 2
            and all(_number(x) for x in u) and isinstance(c, list)):
        raise _fail(path, n, f"malformed tick line: {text.strip()[:80]}")
    if k != expected:
        raise _fail(path, n, f"tick {_short(k)} where tick {expected} was expected")
    if not (_finite_in(u[0], MAX_SPEED) and _finite_in(u[1], MAX_RECORDED_TURN)):
        raise _fail(path, n, f"control u = [{_short(u[0])}, {_short(u[1])}]: expected finite "
                             f"numbers, |v| <= {MAX_SPEED:g} m/s and |omega| <= "
                             f"{MAX_RECORDED_TURN:g} rad/s")
    if len(c) > MAX_COMMANDS:
        raise _fail(path, n, f"{len(c):,} user commands on one tick: expected at most {MAX_COMMANDS}")
    for cmd in c:
        try:
            if not isinstance(cmd, dict):
                raise ValueError(f"user command {_short(cmd)} is not an object")
            validate_command(cmd, 0 if team else None)
        except ValueError as exc:
            raise _fail(path, n, str(exc)) from None
    h, r = obj.get("h"), obj.get("r")
    if not (h is None or isinstance(h, str)) or not (r is None or isinstance(r, str)):
        raise _fail(path, n, f"malformed tick line: {text.strip()[:80]}")
    control = Control(float(u[0]), float(u[1]))
    if not team:
        return TickRecord(k, control, c, h, n, r)
    d, a = obj.get("d"), obj.get("a", False)
    if type(d) is not int or d < 0 or not isinstance(a, bool):
        raise _fail(path, n, f"malformed team tick line (d: the driven robot, a: autopilot): "
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
                        and all(isinstance(p, list) and len(p) == 3 and all(_number(x) for x in p)
                                for p in obj["poses"]))


def _digests_ok(d: Any) -> bool:
    return isinstance(d, dict) and len(d) <= MAX_SENSORS \
        and all(v is None or isinstance(v, str) for v in d.values())


def _values_ok(d: Any) -> bool:
    """An estimates or end line's ``values``: {NAME: nine numbers per robot, or null}."""
    return isinstance(d, dict) and len(d) <= MAX_SENSORS and all(
        v is None or (isinstance(v, list) and 0 < len(v) <= VALUES_PER_ROBOT * MAX_ROBOTS
                      and len(v) % VALUES_PER_ROBOT == 0 and all(_number(x) for x in v))
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
                raise _fail(path, 1, "corrupted header (not one complete JSON object)")
            raise _fail(path, n, "not valid JSON")
        if n == 1:
            _check_header(path, obj)
            header = obj
            team = is_team_header(obj)
            if key is not None and obj.get("signed"):
                signer = Signer(key)
                signer.add(text)
            continue
        if header is None:  # line 1 was blank: every later line needs the header
            raise _fail(path, 1, "corrupted header (missing)")
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
            raise _fail(path, n, "data after the end line")
        if kind == "tick":
            ticks.append(_tick_line(path, n, text, obj, ticks[-1].tick + 1 if ticks else 1, team))
        elif kind == "checkpoint":
            if type(obj.get("k")) is not int or not _state_line_ok(obj, team):
                raise _fail(path, n, "malformed checkpoint line")
            if header["version"] >= 3 and (not ticks or obj["k"] != ticks[-1].tick):
                raise _fail(path, n, f"checkpoint of tick {obj['k']} after the line of tick "
                                     f"{ticks[-1].tick if ticks else 0}")
            if obj["k"] in checkpoints or obj["k"] in parts.estimates:
                # the recorder writes a tick's checkpoint once, before its estimates line
                before = "another checkpoint" if obj["k"] in checkpoints else "its estimates line"
                raise _fail(path, n, f"checkpoint of tick {obj['k']} out of order (after {before} "
                                     "of that tick): was the file edited?")
            checkpoints[obj["k"]] = obj
        elif kind == "estimates" and header["version"] >= 3:
            if type(obj.get("k")) is not int or not _digests_ok(obj.get("digests")) \
                    or not _state_line_ok({"checksum": "", **obj, "estimates": {}}, False):
                raise _fail(path, n, "malformed estimates line")
            if not ticks or obj["k"] != ticks[-1].tick or obj["k"] in parts.estimates:
                raise _fail(path, n, f"estimates of tick {obj['k']} after the line of tick "
                                     f"{ticks[-1].tick if ticks else 0}")
            parts.estimates[obj["k"]] = {**obj, "line": n}
        elif kind == "filters" and header["version"] >= 3 \
                and parts.settings is None and not ticks:
            if not _settings_ok(obj):
                raise _fail(path, n, "malformed filters line")
            parts.settings, parts.settings_line = obj["filters"], n
        elif kind == "end":
            if not _state_line_ok(obj, team):
                raise _fail(path, n, "malformed end line")
            end = obj
        else:
            raise _fail(path, n, f"unknown line type {_short(kind)}")
    if header is None:
        raise _fail(path, 1, "corrupted header (missing)")
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
        raise _fail(path, 1, f"corrupted header: checkpoint_every = {_short(every)}")
    last = ticks[-1].tick if ticks else 0
    due = set(range(every, last + 1, every))
    for what, got in [("checkpoint", set(checkpoints)),
                      *([("estimates", set(parts.estimates))] if parts.settings is not None else [])]:
        missing = sorted(due - got - (set() if ended else {max(due, default=0)}))
        if missing:
            raise _fail(path, 1, f"no {what} line after tick {missing[0]} (one every "
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
        raise _fail(path, 1, f"corrupted header: dt {header['dt']} but the scenario says {dt}")


def _slip_model(path: Path, header: Mapping[str, Any]) -> str:
    """The header's "slip_model" (the motion noise model); "legacy" for a file made before it."""
    model = header.get("slip_model", RECORDED_BEFORE_SLIP_MODEL)
    if model not in SLIP_MODELS:
        raise _fail(path, 1, f"corrupted header: slip_model = {model!r} (expected "
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
            raise _fail(path, rec.line, str(exc)) from None
    for k, obj in [*checkpoints.items(), (-1, end or {"poses": [None] * n})]:
        if len(obj["poses"]) != n:
            raise _fail(path, 1, f"corrupted {'end' if k < 0 else f'checkpoint {k}'}: "
                                 f"{len(obj['poses'])} poses for {n} robots")
    team = replace(team, seed=int(header["seed"]))
    return Recording(path, header, team, ticks, checkpoints, end, notes, parts)
