"""What makes a recording evidence: the scenario text's checksum, the optional HMAC signature,
and the digests and values of the filters' estimates (compared on replay)."""

from __future__ import annotations

import hashlib
import hmac
import json
import os
from collections.abc import Mapping
from typing import Any

import numpy as np

from beacon_sim.hosting.team_runner import TeamRunner
from beacon_sim.io.recording.format import FORMAT_VERSION, KEY_VARIABLE, jsonable


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
    return json.loads(json.dumps(out, default=jsonable, allow_nan=True))


def is_fingerprint(x: Any) -> bool:
    """Whether ``x`` is a maths fingerprint: 16 lower-case hex digits."""
    return isinstance(x, str) and len(x) == 16 and all(ch in "0123456789abcdef" for ch in x)

