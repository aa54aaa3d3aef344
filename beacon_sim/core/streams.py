"""Random streams: one seed per run, a separate generator for every purpose.

``numpy.random.SeedSequence(seed, spawn_key=...)`` keyed by the purpose's *name* (not by an
index), so adding a filter or a sensor never changes any other stream. Nothing in the
project calls the global ``np.random.*`` or ``random.*``.
"""

from __future__ import annotations

import zlib

import numpy as np


def stream(seed: int, purpose: str, name: str = "") -> np.random.Generator:
    """The generator for ``purpose`` (``"motion"``, ``"sensor"``, ``"events"``,
    ``"driver"``, ``"filter"``) and an optional ``name`` (sensor or filter name)."""
    key = (zlib.crc32(purpose.encode()), zlib.crc32(name.encode()))
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed, spawn_key=key)))
