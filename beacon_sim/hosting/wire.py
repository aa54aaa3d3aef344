"""The pipe between the grader and a filter's child process (:mod:`beacon_sim.hosting.child`,
:mod:`beacon_sim.hosting.isolated`): frames of bytes, in lockstep.

Grader -> child: ``length (4 bytes) + pickle`` of a tuple ``(op, *args)``: the child trusts
the grader. Child -> grader: ``tag (1 byte) + length (4 bytes) + payload``, never a pickle
(unpickling lets the sender run code in the receiver): estimates are raw float64 numbers,
messages are UTF-8 JSON of bounded size, and the grader reads at most
``MAX_REPLY_BYTES`` per frame.
"""

from __future__ import annotations

import json
import os
import pickle
import select
import struct
import time
from typing import Any

import numpy as np

from beacon_sim.hosting.landmark_check import MAX_LANDMARKS, landmark_count_problem, landmark_map_problems

#: Reply tags (child -> grader). MULTI: one answer per filter of a seed batch; MAPPED: an
#: ESTIMATE followed by the filter's map (``landmarks()``: a SLAM filter's step).
OK, FAIL, ESTIMATE, BELIEF, REPORT, MULTI, MAPPED = b"K", b"F", b"E", b"B", b"R", b"M", b"L"
_TAGS = (OK, FAIL, ESTIMATE, BELIEF, REPORT, MULTI, MAPPED)
#: A MULTI entry carrying a filter's final ``joint()`` (:func:`encode_joint`).
JOINT = b"J"
#: The largest reply frame the grader reads [bytes] (a belief of a million particles fits).
MAX_REPLY_BYTES = 64 << 20
#: The longest text (a failure's reason or traceback) a reply carries [characters].
MAX_TEXT = 4000

_HEAD = struct.Struct("<I")
_RHEAD = struct.Struct("<cI")
#: An ESTIMATE payload: has_prior flag, wall ns of predict + update + estimate, prior mean (3)
#: and cov (9), posterior mean (3) and cov (9) [m, m, rad], float64 little-endian.
_EST = struct.Struct("<qq24d")
_FLAGS = struct.Struct("<qq")
_EST_HEAD_BYTES = _RHEAD.pack(b"E", _EST.size)
_F8 = np.dtype("<f8")
_NO_PRIOR = (np.full(3, np.nan, dtype=_F8), np.full((3, 3), np.nan, dtype=_F8))


class WireError(RuntimeError):
    """The other end closed the pipe, broke the protocol, or did not answer in time."""


class MapFault(ValueError):
    """A map block that says what was wrong with the filter's ``landmarks()``: its one line."""


def fault_text(raw: bytes) -> str:
    """A child's one line of text, as text (undecodable bytes replaced), on one line."""
    return " ".join(raw.decode("utf-8", "replace").split())[:MAX_TEXT] or "landmarks(): a bad map"


def _read_exact(fd: int, n: int, deadline: float | None) -> bytes:
    out = bytearray()
    while len(out) < n:
        if deadline is not None:
            left = deadline - time.monotonic()
            if left <= 0:
                raise WireError("no answer in time")
            ready, _, _ = select.select([fd], [], [], left)
            if not ready:
                raise WireError("no answer in time")
        chunk = os.read(fd, min(n - len(out), 1 << 20))
        if not chunk:
            raise WireError("closed")
        out += chunk
    return bytes(out)


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        n = os.write(fd, view)
        view = view[n:]


# -- grader -> child -------------------------------------------------------------------

def encode_request(op: str, *args: Any) -> bytes:
    """One request frame (pickled once, so a tick can be sent to many children as is)."""
    body = pickle.dumps((op, *args), protocol=pickle.HIGHEST_PROTOCOL)
    return _HEAD.pack(len(body)) + body


def send_frame(fd: int, frame: bytes) -> None:
    """Write a frame made by :func:`encode_request` (or a reply) to ``fd``."""
    _write_all(fd, frame)


def read_request(fd: int) -> tuple[Any, ...] | None:
    """The next request (child side), or None when the grader closed the pipe. The grader
    sends one request at a time, so one read usually brings the whole frame."""
    try:
        chunk = os.read(fd, 1 << 16)
        if not chunk:
            return None
        if len(chunk) < _HEAD.size:
            chunk += _read_exact(fd, _HEAD.size - len(chunk), None)
        (n,) = _HEAD.unpack_from(chunk)
        body = chunk[_HEAD.size:]
        if len(body) < n:
            body += _read_exact(fd, n - len(body), None)
        return pickle.loads(body)
    except WireError:
        return None


# -- child -> grader -------------------------------------------------------------------

def reply(tag: bytes, payload: bytes = b"") -> bytes:
    """A reply frame."""
    return _RHEAD.pack(tag, len(payload)) + payload


def reply_json(tag: bytes, doc: dict[str, Any]) -> bytes:
    """A reply carrying a small JSON object (texts cut at ``MAX_TEXT`` characters)."""
    doc = {k: (v[:MAX_TEXT] if isinstance(v, str) else v) for k, v in doc.items()}
    return reply(tag, json.dumps(doc).encode("utf-8"))


def reply_estimate(wall_ns: int, prior: tuple[np.ndarray, np.ndarray] | None,
                   post: tuple[np.ndarray, np.ndarray], landmarks: bytes | None = None) -> bytes:
    """An ESTIMATE reply: the estimate after predict (or none) and after update; with
    ``landmarks`` (a map block, :func:`encode_landmarks`) a MAPPED reply: the same numbers,
    then the map."""
    if landmarks is not None:
        return reply(MAPPED, reply_estimate(wall_ns, prior, post)[_RHEAD.size:] + landmarks)
    pm, pc = prior if prior is not None else _NO_PRIOR
    parts: tuple[np.ndarray, ...] = (pm, pc, post[0], post[1])
    if any(type(a) is not np.ndarray or a.dtype != _F8 for a in parts) or pm.shape != (3,) \
            or pc.shape != (3, 3) or post[0].shape != (3,) or post[1].shape != (3, 3):
        parts = tuple(np.asarray(a, dtype=_F8).reshape(n) for a, n in zip(parts, (3, 9, 3, 9), strict=True))
    return b"".join((_EST_HEAD_BYTES, _FLAGS.pack(prior is not None, int(wall_ns)),
                     *(a.tobytes() for a in parts)))  # C order, little-endian float64


def read_reply(fd: int, timeout_s: float | None, expect: int | None = None) -> tuple[bytes, bytes]:
    """The next reply (grader side): (tag, payload). Raises :class:`WireError` when the
    child closed the pipe (it died), sent a frame over ``MAX_REPLY_BYTES`` or an unknown
    tag, or said nothing for ``timeout_s`` [s] of wall time. ``expect``: the reply's likely
    size [bytes], read in one go (then bytes beyond the frame break the protocol too: the
    child answers one request with one frame)."""
    deadline = None if timeout_s is None else time.monotonic() + timeout_s
    head = _read_exact(fd, _RHEAD.size, deadline) if expect is None else _read_some(fd, expect, deadline)
    tag, n = _RHEAD.unpack_from(head)
    if tag not in _TAGS or n > MAX_REPLY_BYTES:
        raise WireError(f"broke the protocol (a {n}-byte frame tagged {tag!r})")
    body = head[_RHEAD.size:]
    if len(body) > n:
        raise WireError(f"broke the protocol (more bytes than its {n}-byte frame)")
    return tag, body + _read_exact(fd, n - len(body), deadline) if len(body) < n else body


def _read_some(fd: int, most: int, deadline: float | None) -> bytes:
    """At least a reply's head and at most ``most`` bytes, in as few reads as the pipe allows
    (one, for a reply of the expected size)."""
    out = b""
    while len(out) < _RHEAD.size:
        if deadline is not None:
            left = deadline - time.monotonic()
            ready = select.select([fd], [], [], left)[0] if left > 0 else []
            if not ready:
                raise WireError("no answer in time")
        chunk = os.read(fd, max(most, _RHEAD.size) - len(out))
        if not chunk:
            raise WireError("closed")
        out += chunk
    return out


def parse_json(payload: bytes) -> dict[str, Any]:
    """A JSON reply's object (a child that sends anything else broke the protocol)."""
    try:
        doc = json.loads(payload.decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as exc:
        raise WireError("broke the protocol (a reply that is not JSON)") from exc
    if not isinstance(doc, dict):
        raise WireError("broke the protocol (a reply that is not a JSON object)")
    return doc


def parse_estimate(payload: bytes) -> tuple[int, tuple[np.ndarray, np.ndarray] | None,
                                             tuple[np.ndarray, np.ndarray]]:
    """(wall ns, prior or None, posterior) of an ESTIMATE reply (or of the estimate part of
    a MAPPED one, :func:`split_mapped`), as fresh float arrays."""
    if len(payload) != _EST.size:
        raise WireError("broke the protocol (an estimate of the wrong size)")
    has_prior, wall_ns, *values = _EST.unpack(payload)
    v = np.array(values)
    prior = (v[0:3].copy(), v[3:12].reshape(3, 3)) if has_prior else None
    return int(wall_ns), prior, (v[12:15].copy(), v[15:24].reshape(3, 3))


# -- a SLAM filter's map: the block a MAPPED reply carries after its estimate --------------

#: A map block's head: the count of landmarks M and whether IDs follow (int64 each).
_MAP_HEAD = struct.Struct("<qq")
#: The longest map block [bytes]: the head, then M int64 IDs, M x 2 means, M x 2 x 2 covs.
MAX_MAP_BYTES = _MAP_HEAD.size + MAX_LANDMARKS * (8 + 16 + 32)


def encode_landmarks(lm: Any) -> bytes | str:
    """The map block of what a filter's ``landmarks()`` returned (child side): bytes, or the
    one-line fault of a map that cannot be sent (not a LandmarkMap, wrong shapes, over
    :data:`~beacon_sim.hosting.landmark_check.MAX_LANDMARKS` landmarks). The values (finite,
    symmetric PSD covariances) are judged by the grader, which trusts nothing it reads."""
    if lm is None or not all(hasattr(lm, a) for a in ("ids", "means", "covs")):
        return landmark_map_problems(lm)[0]
    try:
        raw_ids, raw_means, raw_covs = lm.ids, lm.means, lm.covs
        sizes = [np.shape(a)[0] if np.ndim(a) else 0 for a in (raw_means, raw_covs)]
        if raw_ids is not None:
            sizes.append(np.shape(raw_ids)[0] if np.ndim(raw_ids) else 0)
        big = landmark_count_problem(max(sizes))
        if big is not None:
            return big
        means = np.ascontiguousarray(raw_means, dtype=_F8)
        covs = np.ascontiguousarray(raw_covs, dtype=_F8)
        ids = None if raw_ids is None else np.asarray(raw_ids)
    except (TypeError, ValueError, IndexError, OverflowError):
        return "landmarks(): means or covs are not arrays of numbers"
    m = means.shape[0] if means.ndim == 2 else -1
    if m < 0 or means.shape != (m, 2) or covs.shape != (m, 2, 2) or (
            ids is not None and (ids.shape != (m,) or not np.issubdtype(ids.dtype, np.integer))):
        faults = landmark_map_problems(lm)
        return "; ".join(faults) if faults else "landmarks(): a map of the wrong shapes"
    head = _MAP_HEAD.pack(m, ids is not None)
    id_bytes = b"" if ids is None else ids.astype("<i8").tobytes()
    return head + id_bytes + means.tobytes() + covs.tobytes()


def map_fault_block(why: str) -> bytes:
    """A map block that carries the fault of what ``landmarks()`` returned (or raised)
    instead of a map: M = -1, then the one line in UTF-8 (at most ``MAX_TEXT`` characters).
    The grader switches the filter off with it, or (``check``) reports it as the map check's
    finding while the pose checks go on."""
    text = why[:MAX_TEXT].encode("utf-8")
    return _MAP_HEAD.pack(-1, len(text)) + text


def split_mapped(payload: bytes) -> tuple[bytes, bytes]:
    """(the ESTIMATE payload, the map block) of a MAPPED reply's payload."""
    if not _EST.size + _MAP_HEAD.size <= len(payload) <= _EST.size + MAX_MAP_BYTES:
        raise WireError("broke the protocol (a map reply of the wrong size)")
    return payload[:_EST.size], payload[_EST.size:]


def decode_landmarks(block: bytes) -> tuple[np.ndarray | None, np.ndarray, np.ndarray]:
    """(ids (M,) or None, means (M, 2) [m], covs (M, 2, 2) [m^2]) of a map block (grader
    side), fresh arrays; their values are not judged here
    (:func:`~beacon_sim.hosting.landmark_check.landmark_map_problems` does). Raises
    :class:`WireError` for a block whose size does not match its head or over the limit,
    :class:`MapFault` for a block that carries a fault (:func:`map_fault_block`)."""
    if len(block) < _MAP_HEAD.size:
        raise WireError("broke the protocol (a short map)")
    m, has_ids = _MAP_HEAD.unpack_from(block)
    if m == -1 and 0 <= has_ids <= 12 * MAX_TEXT and len(block) == _MAP_HEAD.size + has_ids:
        raise MapFault(fault_text(block[_MAP_HEAD.size:]))
    if not 0 <= m <= MAX_LANDMARKS or has_ids not in (0, 1) \
            or len(block) != _MAP_HEAD.size + m * (8 * has_ids + 16 + 32):
        raise WireError("broke the protocol (a malformed map)")
    at = _MAP_HEAD.size
    ids = None
    if has_ids:
        ids = np.frombuffer(block, dtype="<i8", count=m, offset=at).astype(np.int64)
        at += 8 * m
    means = np.frombuffer(block, dtype=_F8, count=2 * m, offset=at).reshape(m, 2).copy()
    covs = np.frombuffer(block, dtype=_F8, count=4 * m, offset=at + 16 * m).reshape(m, 2, 2).copy()
    return ids, means, covs


def map_problem(block: bytes) -> tuple[tuple[np.ndarray | None, np.ndarray, np.ndarray] | None, str | None]:
    """A map block judged as the grader judges every map: (the map, None), or (None, the
    one-line fault that switches the filter off: NaN, a covariance not symmetric PSD...).
    A malformed block raises :class:`WireError` (the child broke the protocol)."""
    from beacon_sim.filters.base import LandmarkMap

    try:
        ids, means, covs = decode_landmarks(block)
    except MapFault as exc:
        return None, str(exc)
    faults = landmark_map_problems(LandmarkMap(ids, means, covs))
    if faults:
        return None, "; ".join(faults)
    return (ids, means, covs), None


# -- a batch of seeds: one exchange per tick for all of a student's runs ------------------

#: The most landmarks of a ``joint()`` a child sends (its covariance: (3 + 2M)^2 numbers).
MAX_JOINT_LANDMARKS = 500
#: The longest joint entry of a MULTI reply [bytes] (a BELIEF: its JSON head, three arrays).
MAX_JOINT_BYTES = 8 * (3 + 2 * MAX_JOINT_LANDMARKS) * (4 + 2 * MAX_JOINT_LANDMARKS) + 1024

#: The largest batch (filters in one child answered in one MULTI reply: under 1 MB).
MAX_BATCH = 4096
#: The longest FAIL entry of a MULTI reply [bytes] (its JSON: a reason and a traceback).
MAX_FAIL_BYTES = 2 * 12 * MAX_TEXT + 64  # two texts, each char escaped to at most 12 bytes
#: One ESTIMATE entry of a MULTI reply as a numpy record: the reply head (tag, length) then
#: the ESTIMATE payload (:data:`_EST`), packed (213 bytes).
EST_ENTRY = np.dtype([("tag", "S1"), ("n", "<u4"), ("prior", "<i8"), ("wall", "<i8"), ("v", "<f8", (24,))])
_EST_HEAD = [bytes([c]) for c in _RHEAD.pack(ESTIMATE, _EST.size)]


def encode_batch(op: str, bodies: list[bytes], *args: Any) -> bytes:
    """A batch request ``(op, bodies, *args)``: ``bodies`` are the per-filter requests'
    pickles (:func:`encode_request` frames without their 4-byte head), made once and sent
    to every student as they are."""
    return encode_request(op, bodies, *args)


def reply_multi(entries: list[bytes]) -> bytes:
    """A MULTI reply: one reply frame (OK, ESTIMATE or FAIL) per filter of the batch, in the
    order of the request."""
    return reply(MULTI, b"".join(entries))


def parse_multi(payload: bytes, count: int) -> list[tuple[bytes, bytes]] | np.ndarray:
    """The ``count`` entries of a MULTI reply: a record array of :data:`EST_ENTRY` when every
    entry is an ESTIMATE (the common tick, read in one call), else a list of (tag, payload).
    Raises :class:`WireError` for anything but exactly ``count`` well-formed OK, ESTIMATE,
    MAPPED or FAIL entries (an ESTIMATE of the wrong size, a FAIL over ``MAX_FAIL_BYTES``, a
    MAPPED over ``MAX_MAP_BYTES`` of map)."""
    size = EST_ENTRY.itemsize
    if len(payload) == count * size and all(
            payload[j::size] == b * count for j, b in enumerate(_EST_HEAD)):  # every head E, 208
        return np.frombuffer(payload, dtype=EST_ENTRY, count=count)
    out: list[tuple[bytes, bytes]] = []
    at, view = 0, memoryview(payload)
    for _ in range(count):
        if at + _RHEAD.size > len(payload):
            raise WireError("broke the protocol (a short batch answer)")
        tag, n = _RHEAD.unpack_from(payload, at)
        at += _RHEAD.size
        sizes = {OK: 0, ESTIMATE: _EST.size}
        most = {MAPPED: _EST.size + MAX_MAP_BYTES, JOINT: MAX_JOINT_BYTES}.get(tag, MAX_FAIL_BYTES)
        if tag not in (OK, ESTIMATE, FAIL, MAPPED, JOINT) or n != sizes.get(tag, n) or n > most \
                or at + n > len(payload):
            raise WireError(f"broke the protocol (a batch entry of {n} bytes tagged {tag!r})")
        out.append((tag, bytes(view[at:at + n])))
        at += n
    if at != len(payload):
        raise WireError("broke the protocol (a batch answer with more entries than asked)")
    return out


def encode_joint(mean: np.ndarray, cov: np.ndarray, ids: np.ndarray) -> bytes:
    """A JOINT entry of a MULTI reply: a filter's final ``joint()`` as a belief-style
    payload (kind "joint", three float64 arrays)."""
    return reply(JOINT, encode_belief("joint", [mean, cov, ids], {})[_RHEAD.size:])


def decode_joint(payload: bytes) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(mean (n,), cov (n, n), landmark IDs (M,) int) of a JOINT entry's payload (grader
    side), with n = 3 + 2M, every number finite and the IDs whole; None for anything else
    (then no joint NEES is reported: the filter is not failed for it)."""
    try:
        kind, arrays, _ = decode_belief(payload)
    except WireError:
        return None
    if kind != "joint" or len(arrays) != 3:
        return None
    mean, cov, ids = arrays
    m = ids.size
    n = 3 + 2 * m
    if ids.shape != (m,) or mean.shape != (n,) or cov.shape != (n, n) or m > MAX_JOINT_LANDMARKS:
        return None
    if not (np.all(np.isfinite(mean)) and np.all(np.isfinite(cov)) and np.all(np.isfinite(ids))) \
            or np.any(ids != np.round(ids)) or np.any(np.abs(ids) > 2**53):
        return None
    return mean, cov, ids.astype(np.int64)


def encode_belief(kind: str, arrays: list[np.ndarray], extra: dict[str, Any]) -> bytes:
    """A BELIEF reply: a JSON header (kind, shapes, extra numbers) then raw float64 arrays."""
    arrays = [np.ascontiguousarray(a, dtype="<f8") for a in arrays]
    head = json.dumps({"kind": kind, "shapes": [list(a.shape) for a in arrays], **extra}).encode()
    return reply(BELIEF, _HEAD.pack(len(head)) + head + b"".join(a.tobytes() for a in arrays))


def decode_belief(payload: bytes) -> tuple[str, list[np.ndarray], dict[str, Any]]:
    """(kind, arrays, header) of a BELIEF reply; sizes are checked against the header."""
    try:
        (n,) = _HEAD.unpack(payload[:4])
        head = json.loads(payload[4:4 + n].decode("utf-8"))
        body = memoryview(payload)[4 + n:]
        arrays, at = [], 0
        for shape in head["shapes"]:
            size = int(np.prod(shape, dtype=np.int64)) * 8
            if size < 0 or at + size > len(body):
                raise ValueError("short")
            arrays.append(np.frombuffer(body[at:at + size], dtype="<f8").reshape(shape).copy())
            at += size
        return str(head["kind"]), arrays, head
    except (ValueError, KeyError, TypeError, struct.error) as exc:
        raise WireError("broke the protocol (a malformed belief)") from exc


__all__ = ["BELIEF", "ESTIMATE", "EST_ENTRY", "FAIL", "MAPPED", "MAX_BATCH", "MAX_MAP_BYTES",
           "MULTI", "OK", "REPORT", "MapFault", "WireError", "decode_belief", "decode_joint",
           "decode_landmarks", "encode_batch", "encode_belief", "encode_joint", "encode_landmarks",
           "encode_request", "fault_text", "map_fault_block", "map_problem", "parse_estimate",
           "parse_json", "parse_multi", "read_reply", "read_request", "reply", "reply_estimate",
           "reply_json", "reply_multi", "send_frame", "split_mapped"]
