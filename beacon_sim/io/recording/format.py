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

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from beacon_sim.core.scenario import (
    MAX_COORD,
)
from beacon_sim.core.types import Control
from beacon_sim.errors import BeaconSimError

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


def short_text(x: Any) -> str:
    text = repr(x)
    return text if len(text) <= 60 else text[:57] + "..."


def check_pose(pose: Any) -> None:
    """Raise ValueError unless ``pose`` is ``[x, y, theta]``: three finite numbers within
    MAX_COORD [m, m, rad]."""
    if not (isinstance(pose, list | tuple) and len(pose) == 3
            and all(is_number(x) and finite_within(x, MAX_COORD) for x in pose)):
        raise ValueError(f"kidnap pose {short_text(pose)}: expected [x, y, theta], three finite "
                         f"numbers within +-{MAX_COORD:g} (metres, radians)")


def check_toggle(cmd: Mapping) -> None:
    name = cmd.get("filter")
    if not isinstance(name, str) or len(name) > MAX_NAME_CHARS:
        raise ValueError(f"toggle of {short_text(name)}: expected a filter name (a string of at "
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
        raise ValueError(f"unknown {'team' if team else 'user'} command {short_text(kind)}; "
                         f"expected one of {kinds}")
    if kind == "kidnap" and team:
        robot = cmd.get("robot")
        if not isinstance(robot, int) or isinstance(robot, bool) or robot < 0 \
                or (n_robots is not None and n_robots > 0 and robot >= n_robots):
            raise ValueError(f"kidnap of robot {short_text(robot)}: expected a robot index"
                             + (f" from 0 to {n_robots - 1}" if n_robots else ""))
    if kind == "kidnap" and "pose" in cmd:
        check_pose(cmd["pose"])
    if kind == "toggle":
        check_toggle(cmd)


def jsonable(x: Any) -> Any:
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


def failure(path: Path, line: int, what: str) -> RecordingError:
    return RecordingError(f"{path}:{line}: {what}")


def is_number(x) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool)


def finite_within(x: float, limit: float) -> bool:
    """Whether the number ``x`` (int or float) is finite and within +-``limit``."""
    try:
        return math.isfinite(float(x)) and abs(x) <= limit
    except OverflowError:  # an integer too large for a float
        return False

