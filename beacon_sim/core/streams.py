"""Random streams: one seed per run, a separate generator for every purpose.

``numpy.random.SeedSequence(seed, spawn_key=...)`` keyed by the purpose's *name* (not by an
index), so adding a filter or a sensor never changes any other stream. Nothing in the
project calls the global ``np.random.*`` or ``random.*``.

A filter's own generator is different: a filter is somebody else's code, and a
generator whose ``SeedSequence`` holds the run's seed (its ``entropy``, readable from
``ctx.rng.bit_generator.seed_seq``, and pickled with it) hands that code the seed, from
which it re-simulates the truth. So a filter's stream comes from a *run key*: SHA-256 of a
key and the run's seed (:func:`run_key`), hashed again with the filter's name
(:func:`filter_stream`); what the filter can read is a hash, never the seed. ``grade`` keys
it with a secret it draws for the grade and never sends to a child; ``run``, ``eval``,
``check``'s in-process filters, the window and replays with the fixed :data:`PUBLIC_KEY`, so
their results stay reproducible from the seed alone (and a filter there could still try
every small seed against the hash: only a secret closes that).
"""

from __future__ import annotations

import hashlib
import zlib

import numpy as np

#: The key of every filter stream outside ``grade`` (``run``, ``eval``, the window, replays):
#: public, so those results are reproducible from the seed alone.
PUBLIC_KEY = b"beacon-sim public filter streams"
#: The length of a grade's secret [bytes] (drawn with :func:`secrets.token_bytes`).
SECRET_BYTES = 32


def stream(seed: int, purpose: str, name: str = "") -> np.random.Generator:
    """The generator for ``purpose`` (``"motion"``, ``"sensor"``, ``"events"``,
    ``"driver"``, ``"clutter"``) and an optional ``name`` (sensor name). Not for filters:
    their generators come from :func:`filter_stream`, which does not hand them the seed."""
    if purpose == "filter":
        raise ValueError("a filter's generator comes from filter_stream (it must not hold the seed)")
    key = (zlib.crc32(purpose.encode()), zlib.crc32(name.encode()))
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed, spawn_key=key)))


def _digest(*parts: bytes) -> bytes:
    """SHA-256 of ``parts``, each prefixed by its length (no two lists of parts collide)."""
    h = hashlib.sha256()
    for p in parts:
        h.update(len(p).to_bytes(8, "little"))
        h.update(p)
    return h.digest()


def run_key(seed: int, secret: bytes | None = None) -> bytes:
    """The key of one run's filter streams (32 bytes): SHA-256 of ``secret`` (None: the
    public key) and the run's ``seed``. Whoever holds it holds no more than the run's
    filter streams: the seed does not follow from it."""
    return _digest(b"beacon-sim run key v1", PUBLIC_KEY if secret is None else bytes(secret),
                   str(int(seed)).encode())


def keyed_stream(key: bytes, name: str) -> np.random.Generator:
    """The generator of the filter ``name`` in the run whose key is ``key`` (:func:`run_key`):
    a ``SeedSequence`` whose entropy is SHA-256 of the key and the name (256 bits)."""
    entropy = int.from_bytes(_digest(b"beacon-sim filter stream v1", key, name.encode()), "little")
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(entropy)))


def filter_stream(seed: int, name: str, secret: bytes | None = None) -> np.random.Generator:
    """``ctx.rng`` of the filter ``name`` in the run ``seed``, keyed by ``secret`` (None: the
    public key): the same generator for the same three, another for any other filter or
    run, and nothing in it that gives the seed away (only a hash of it)."""
    return keyed_stream(run_key(seed, secret), name)


def keyed_global_seed(key: bytes, name: str) -> int:
    """The seed (128 bits) of the global ``np.random`` and ``random`` generators of a
    hosted filter ``name`` in the run whose key is ``key``: derived like its stream, never
    the run's seed (``np_random_seed`` in hosting/child.py seeds them with it)."""
    return int.from_bytes(_digest(b"beacon-sim global rng v1", key, name.encode())[:16], "little")


__all__ = ["PUBLIC_KEY", "SECRET_BYTES", "filter_stream", "keyed_global_seed", "keyed_stream", "run_key",
           "stream"]
