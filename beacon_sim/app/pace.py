"""How fast the window really goes: frames per second, and the speed factor the simulation
delivers (under load the clock drops ticks, so "x8" may be less in truth).
"""

from __future__ import annotations

from collections import deque

import numpy as np


def fps_of(frame_times: np.ndarray) -> float:
    """Frames per second from recent frame durations [s]."""
    if not len(frame_times):
        return 0.0
    m = float(np.mean(frame_times))
    return 1.0 / m if m > 0 else 0.0


class DeliveredSpeed:
    """The speed factor the simulation actually delivers: simulated seconds per second of
    the window's clock over the last :attr:`SPAN_S` (None until that long has been seen at
    one speed and running). Under load the clock drops ticks, so the panel's "x8" can be
    0.85 in truth; the panel shows this figure when it falls short."""

    SPAN_S = 2.0

    def __init__(self) -> None:
        self.samples: deque[tuple[float, float]] = deque()
        self._key: tuple | None = None

    def sample(self, now: float, sim_time: float, speed: float, paused: bool) -> None:
        """After a frame: the window's clock [s], the simulated time [s], the asked speed."""
        key = (speed, paused)
        if key != self._key or (self.samples and sim_time < self.samples[-1][1]):
            self.samples.clear()  # a new speed, a pause or a seek back: measure afresh
            self._key = key
        self.samples.append((now, sim_time))
        while len(self.samples) > 2 and now - self.samples[1][0] >= self.SPAN_S:
            self.samples.popleft()

    @property
    def factor(self) -> float | None:
        if len(self.samples) < 2 or self._key is None or self._key[1]:
            return None
        (t0, s0), (t1, s1) = self.samples[0], self.samples[-1]
        if t1 - t0 < self.SPAN_S * 0.99:
            return None
        return (s1 - s0) / (t1 - t0)
