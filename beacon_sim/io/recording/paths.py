"""Where a recording is written: the default path under ``recordings/`` and an exclusive create."""

from __future__ import annotations

import datetime as _dt
import os
from pathlib import Path
from typing import TextIO

from beacon_sim.io.recording.format import RECORDINGS_DIR, RecordingError


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

