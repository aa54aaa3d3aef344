"""A one-line progress bar on stderr for long work (a long headless run, an evaluation)."""

from __future__ import annotations

import sys
import time

#: The bar appears only once the work has taken this long [s], and is redrawn at most this
#: often: short work prints nothing, long work does not spend its time drawing.
SHOW_AFTER_S = 1.0
REDRAW_EVERY_S = 0.1


class Progress:
    """``total`` units of work (``unit``: "runs", "ticks"), drawn on stderr when ``enabled``
    (callers pass whether stderr is a terminal)."""

    def __init__(self, total: int, label: str, enabled: bool, unit: str = "runs"):
        self.total, self.label, self.enabled, self.unit = total, label, enabled, unit
        self.done = 0
        self.t0 = self._drawn = time.perf_counter()
        self._shown = False

    def advance(self) -> None:
        self.done += 1
        if not self.enabled:
            return
        now = time.perf_counter()
        last = self.done == self.total
        if now - self.t0 < SHOW_AFTER_S or (now - self._drawn < REDRAW_EVERY_S and not last):
            return
        if last and not self._shown:
            return  # finished before it was worth showing
        self._drawn, self._shown = now, True
        width = 30
        filled = round(width * self.done / max(self.total, 1))
        el = now - self.t0
        eta = el / self.done * (self.total - self.done)
        sys.stderr.write(f"\r{self.label} [{'#' * filled}{'.' * (width - filled)}] "
                         f"{self.done}/{self.total} {self.unit}  {el:5.1f} s  eta {eta:5.1f} s ")
        if last:
            sys.stderr.write("\n")
        sys.stderr.flush()
