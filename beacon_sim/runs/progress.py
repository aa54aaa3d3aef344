"""Progress of long work (a long headless run, an evaluation, a grade) on stderr: a one-line
bar redrawn in place on a terminal, plain periodic lines anywhere else (a log file, nohup,
CI), so a long job is never silent."""

from __future__ import annotations

import sys
import time
from typing import TextIO

#: Progress appears only once the work has taken this long [s]: short work prints nothing.
SHOW_AFTER_S = 1.0
#: A terminal's bar is redrawn at most this often [s].
REDRAW_EVERY_S = 0.1
#: Off a terminal, a line at most this often [s], and a last one when the work is done.
LINE_EVERY_S = 5.0


class Progress:
    """``total`` units of work (``unit``: "runs", "ticks") labelled ``label``, reported on
    ``stream`` (default stderr) when ``enabled``: a bar when the stream is a terminal, else a
    line ``label: done/total unit, elapsed s, eta s`` every :data:`LINE_EVERY_S`."""

    def __init__(self, total: int, label: str, enabled: bool, unit: str = "runs",
                 stream: TextIO | None = None):
        self.total, self.label, self.enabled, self.unit = total, label, enabled, unit
        self.stream = stream
        self.done = 0
        self.t0 = self._drawn = time.perf_counter()
        self._shown = False

    def _out(self) -> TextIO:
        return self.stream if self.stream is not None else sys.stderr

    def advance(self, n: int = 1) -> None:
        """``n`` more units done."""
        self.update(self.done + n)

    def update(self, done: int) -> None:
        """``done`` units done so far."""
        self.done = done
        if not self.enabled:
            return
        out = self._out()
        try:
            tty = out.isatty()
        except (AttributeError, ValueError):
            tty = False
        now = time.perf_counter()
        last = self.done >= self.total
        every = REDRAW_EVERY_S if tty else LINE_EVERY_S
        if now - self.t0 < SHOW_AFTER_S or (now - self._drawn < every and self._shown and not last):
            return
        if last and not self._shown and tty:
            return  # finished before a bar was worth drawing (a log still gets its line)
        self._drawn, self._shown = now, True
        el = now - self.t0
        eta = el / max(self.done, 1) * (self.total - self.done)
        if tty:
            width = 30
            filled = round(width * self.done / max(self.total, 1))
            out.write(f"\r{self.label} [{'#' * filled}{'.' * (width - filled)}] "
                      f"{self.done}/{self.total} {self.unit}  {el:5.1f} s  eta {eta:5.1f} s ")
            if last:
                out.write("\n")
        else:
            out.write(f"{self.label}: {self.done}/{self.total} {self.unit}, {el:.1f} s"
                      + (" (done)\n" if last else f", eta {eta:.1f} s\n"))
        out.flush()
