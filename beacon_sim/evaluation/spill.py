"""Columns of float64 values that grow run by run, parked in temporary files until a
reduction over all of them reads each back whole (``summary.Evaluation``: the means over
every run's steps, which numpy sums pairwise over the whole array, an order no running sum
reproduces bit for bit). In memory the columns cost nothing per run; reading one back costs
8 bytes a value for as long as its reduction runs. Where no temporary file can be written,
the values stay in memory instead (the same results)."""

from __future__ import annotations

import tempfile
from typing import IO

import numpy as np


class SpilledColumns:
    """Named columns of float64: :meth:`append` a run's values, :meth:`read` a whole column
    (every value appended, in order). :meth:`close` deletes the files (also on garbage
    collection)."""

    def __init__(self) -> None:
        self._files: dict[str, IO[bytes]] = {}
        self._memory: dict[str, list[np.ndarray]] = {}
        self._sizes: dict[str, int] = {}

    def append(self, name: str, values: np.ndarray) -> None:
        """Add ``values`` (any shape, taken flat as float64) to the end of column ``name``."""
        a = np.ascontiguousarray(values, dtype=np.float64).ravel()
        before = self._sizes.get(name, 0)
        self._sizes[name] = before + a.size
        if name not in self._memory:
            try:
                fh = self._files.get(name)
                if fh is None:
                    fh = self._files[name] = tempfile.TemporaryFile(prefix="beacon-sim-eval-")
                fh.write(a.tobytes())
                return
            except OSError:   # no room or no folder for temporary files: keep them here
                self._memory[name] = [self._take_back(name, before)]
        self._memory[name].append(a.copy())

    def _take_back(self, name: str, n: int) -> np.ndarray:
        """The first ``n`` values of column ``name``'s file (what was written whole before a
        write failed), closing it."""
        fh = self._files.pop(name, None)
        if fh is None:
            return np.empty(0)
        try:
            fh.seek(0)
            return np.frombuffer(fh.read(8 * n), dtype=np.float64).copy()
        finally:
            fh.close()

    def read(self, name: str) -> np.ndarray:
        """Every value of column ``name`` in the order appended, (n,) float64."""
        if name in self._memory:
            return np.concatenate(self._memory[name]) if self._memory[name] else np.empty(0)
        fh = self._files.get(name)
        if fh is None:
            return np.empty(0)
        fh.flush()
        fh.seek(0)
        out = np.fromfile(fh, dtype=np.float64, count=self._sizes[name])
        if out.size != self._sizes[name]:
            raise OSError(f"temporary file of {name}: read {out.size} of {self._sizes[name]} values")
        fh.seek(0, 2)
        return out

    def size(self, name: str) -> int:
        """How many values column ``name`` holds."""
        return self._sizes.get(name, 0)

    def close(self) -> None:
        for fh in self._files.values():
            fh.close()
        self._files.clear()
        self._memory.clear()

    def __del__(self) -> None:
        self.close()
