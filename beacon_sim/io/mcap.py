"""A run as an MCAP file for Foxglove (``beacon-sim export FILE --out run.mcap``, ``run.export``).

Written with Foxglove's own SDK (``foxglove-sdk``, the ``mcap`` extra): the messages are in
Foxglove's official schemas (protobuf, the schemas embedded in the file), so its 3D, Plot and
Log panels show them without a plug-in. The topics are those of
:class:`beacon_sim.io.foxglove.Publisher` (the table in :mod:`beacon_sim.io.foxglove`), fed with
the arrays of :mod:`beacon_sim.io.export`, so the MCAP, ``.npz`` and ``.csv`` exports hold the
same numbers; a metadata record ``beacon-sim`` holds the scenario, dt, seed and checksum.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import BinaryIO

import numpy as np

from beacon_sim.core.files import atomic_output, write_text_atomic
from beacon_sim.core.scenario import Scenario
from beacon_sim.errors import BeaconSimError
from beacon_sim.io.foxglove import INSTALL_HINT, BeliefFrame, Publisher, foxglove_modules, layout
from beacon_sim.io.tables import prefixed, reading_matrix, upgrade_arrays

__all__ = ["INSTALL_HINT", "write_mcap"]


def write_mcap(path: Path | str, scenario: Scenario, arrays: Mapping[str, np.ndarray],
               metadata: Mapping[str, str] | None = None,
               frames: Mapping[int, BeliefFrame] | None = None) -> Path:
    """Write the run in ``arrays`` (step arrays, plus filter arrays when filters ran) to an
    MCAP file at ``path`` (replaced if it exists), tick by tick in time order; ``metadata``
    goes into the ``beacon-sim`` metadata record; ``frames`` (tick -> :class:`BeliefFrame`,
    kept while the run went: :func:`beacon_sim.io.foxglove.read_frame`) adds the particles,
    grid beliefs, SLAM maps and PCRB of those ticks. Beside it, ``X.layout.json``: a layout
    for the Foxglove app that opens the file's topics (:func:`beacon_sim.io.foxglove.layout`).
    Returns the path."""
    fox, _, _ = foxglove_modules()
    from beacon_sim.version import __version__

    a = upgrade_arrays(arrays)
    path = Path(path)
    names = [str(n) for n in a.get("filter_names", [])]
    with atomic_output(path, what="MCAP file") as tmp:  # the old file stays until this one is whole
        try:
            with open(tmp, "wb") as raw:
                sink = _QuietSink(raw)
                topics = _write(fox, sink, scenario, a, names, metadata, __version__, frames or {})
                sink.finish()
        except (OSError, BeaconSimError):
            raise
        except Exception as exc:
            if not type(exc).__module__.startswith("foxglove"):
                raise
            # the SDK's own error (a full disk while it writes): one line naming the file
            why = " ".join(str(exc).split())[:200] or type(exc).__name__
            raise BeaconSimError(f"{path}: cannot write the MCAP file: {why} (the previous file, "
                                 "if any, is unchanged)") from None
    write_text_atomic(layout_path(path), json.dumps(layout(topics, names), indent=1) + "\n",
                      what="Foxglove layout")
    return path


class _QuietSink:
    """The file the SDK writes through (``write``, ``seek``, ``flush``). The first error (a
    full disk) is kept and every later write skipped, so the SDK does not log a line per
    message; :meth:`finish` raises it once the SDK is done (the caller's one line)."""

    def __init__(self, fh: BinaryIO):
        self.fh = fh
        self.error: OSError | None = None

    def write(self, data: bytes) -> int:
        if self.error is None:
            try:
                self.fh.write(data)
            except OSError as exc:
                self.error = exc
        return len(data)

    def seek(self, offset: int, whence: int = 0) -> int:
        if self.error is None:
            try:
                return self.fh.seek(offset, whence)
            except OSError as exc:  # (a seek flushes the buffer first)
                self.error = exc
        return offset if whence == 0 else 0

    def tell(self) -> int:
        return self.fh.tell() if self.error is None else 0

    def flush(self) -> None:
        if self.error is None:
            try:
                self.fh.flush()
            except OSError as exc:
                self.error = exc

    def finish(self) -> None:
        """Flushed and on the disk, or the first error raised."""
        self.flush()
        if self.error is None:
            try:
                os.fsync(self.fh.fileno())
            except OSError as exc:
                self.error = exc
        if self.error is not None:
            raise self.error


def layout_path(path: Path | str) -> Path:
    """The Foxglove layout written beside an MCAP file: ``run.mcap`` -> ``run.layout.json``."""
    path = Path(path)
    return path.with_name(f"{path.stem}.layout.json")


def _write(fox, tmp: Path | _QuietSink, scenario: Scenario, a: Mapping[str, np.ndarray], names: list[str],
           metadata: Mapping[str, str] | None, version: str, frames: Mapping[int, BeliefFrame]) -> list[str]:
    context = fox.Context()  # this file's channels only
    writer = fox.open_mcap(tmp, allow_overwrite=True, context=context)
    pub = Publisher(scenario, names, context)
    try:
        readings, events = prefixed(a, "readings"), prefixed(a, "events")
        z = reading_matrix(readings)
        by_tick_r: dict[int, list] = {}
        for j, k in enumerate(readings["tick"]):
            by_tick_r.setdefault(int(k), []).append(
                (str(readings["sensor"][j]), str(readings["kind"][j]), z[j], int(readings["beacon_id"][j])))
        by_tick_e: dict[int, list] = {}
        for j, k in enumerate(events["tick"]):
            by_tick_e.setdefault(int(k), []).append((str(events["kind"][j]), str(events["detail"][j])))
        truth = np.asarray(a["truth"], dtype=float)
        last_tick = len(truth) - 1
        # a switched-off filter's failure is logged on the tick after its last estimate
        fail_at: dict[int, list[tuple[str, str]]] = {}
        for i, name in enumerate(names):
            why = str(a["filter_failed"][i])
            if why:
                rows = np.flatnonzero(~np.isnan(a["est_mean"][i]).all(axis=1))
                last = int(rows[-1]) + 1 if len(rows) else 0
                fail_at.setdefault(min(last + 1, last_tick), []).append((name, why))
        pub.start(0)
        for k in range(len(truth)):
            est = {}
            if k >= 1:
                for i, name in enumerate(names):
                    mean = a["est_mean"][i][k - 1]
                    if not np.isnan(mean).all():
                        est[name] = (mean, a["est_cov"][i][k - 1])
            pub.tick(k, truth[k], est, by_tick_r.get(k, ()), by_tick_e.get(k, ()), frames.get(k))
            for name, why in fail_at.get(k, ()):
                pub.failed(k, name, why)
        meta = {"scenario": scenario.name, "dt_s": repr(scenario.dt), "library": f"beacon-sim {version}"}
        meta.update(metadata or {})
        writer.write_metadata("beacon-sim", {k: str(v) for k, v in meta.items()})
        return pub.topics
    finally:
        pub.close()
        writer.close()
