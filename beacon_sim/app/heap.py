"""Keep Python's cyclic garbage collector out of the window's frames.

A full collection walks every tracked object of the process: the modules, numpy, pygame,
fonts, the session's history. In the window that is 12-17 ms at once (measured on the
2-core machine, heavy view at 1280x800: two such frames in 240), a visible stutter every
few seconds, and it finds nothing to free (the window makes almost no cyclic garbage).
:func:`settle` collects once and moves every object that exists then into the
collector's permanent generation (``gc.freeze``): later collections walk only what was made
since. Objects are still freed by reference counting as before; what a frozen object cannot
be any more is collected as part of a cycle (a frozen cycle that becomes garbage stays in
memory). The window settles at its start and then every :data:`SETTLE_EVERY_S` seconds of
its clock on a frame with no simulation tick, after a collection of the young generations
(a fraction of a millisecond), so what is frozen is what survived; when its loop ends it
unfreezes (:meth:`HeapSettler.release`), so the process's garbage is collectable again.
Nothing here changes a result: the collector frees memory, it never runs the simulation or
the filters.
"""

from __future__ import annotations

import gc

#: Seconds of the window's clock between two settles (the heap grows by about 3 tracked
#: objects a tick on global_kidnap; a full collection after a settle took 0.04-0.07 ms).
SETTLE_EVERY_S = 30.0


def settle(full: bool = True) -> None:
    """Collect (every generation with ``full``, else the two young ones) and freeze what
    is left, so that later collections skip it."""
    gc.collect(2 if full else 1)
    gc.freeze()


class HeapSettler:
    """Calls :func:`settle` at the window's start and then every ``every_s`` seconds [s]."""

    def __init__(self, every_s: float = SETTLE_EVERY_S):
        self.every_s = every_s
        self.last: float | None = None

    def offer(self, now: float, busy: bool) -> bool:
        """After a frame at window time ``now`` [s]; ``busy``: the frame ran a tick (then wait
        for a lighter frame). Returns whether it settled."""
        if self.last is None:
            settle(full=True)
        elif busy or now - self.last < self.every_s:
            return False
        else:
            settle(full=False)
        self.last = now
        return True

    def release(self) -> None:
        """Unfreeze what was frozen (``gc.unfreeze``: back in the oldest generation, where a
        later full collection sees it), and settle afresh at the next offer."""
        if self.last is not None:
            gc.unfreeze()
            self.last = None
