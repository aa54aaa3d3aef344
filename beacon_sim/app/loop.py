"""The fixed-step clock: how many simulation ticks to run this frame.

Real (wall) time is accumulated, multiplied by the speed factor, and spent in whole ticks of
``dt`` seconds. The number of ticks per frame is capped: when the machine cannot keep up,
the simulation slows down instead of spiralling. The ticks themselves never depend on the
frame rate, so a window session equals a headless run fed the same commands.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

#: Speed factors reachable with + / - (x0.1: one tick of sparse_kidnap per second, slow
#: enough to talk a class through global localization).
SPEEDS = (0.1, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0)


@dataclass
class StepClock:
    """Accumulator for a fixed simulation step.

    Attributes
    ----------
    dt : float
        Simulation tick [s].
    max_steps_per_frame : int
        Cap on ticks run in one frame; time beyond it is dropped.
    speed_index : int
        Index into ``SPEEDS`` (default x1).
    paused : bool
        While paused, only ``single_step`` requests advance the simulation.
    """

    dt: float
    max_steps_per_frame: int = 8
    speed_index: int = SPEEDS.index(1.0)
    paused: bool = False
    accumulator: float = 0.0
    dropped_s: float = 0.0
    _single_steps: int = field(default=0, repr=False)

    @property
    def speed(self) -> float:
        """Simulated seconds per real second."""
        return SPEEDS[self.speed_index]

    def faster(self) -> None:
        self.speed_index = min(self.speed_index + 1, len(SPEEDS) - 1)

    def slower(self) -> None:
        self.speed_index = max(self.speed_index - 1, 0)

    def set_speed(self, factor: float) -> None:
        """The speed factor in ``SPEEDS`` nearest to ``factor`` (on a log scale)."""
        self.speed_index = min(range(len(SPEEDS)),
                               key=lambda i: abs(math.log(SPEEDS[i] / max(factor, 1e-6))))

    def toggle_pause(self) -> None:
        self.paused = not self.paused
        self.accumulator = 0.0

    def single_step(self) -> None:
        """Ask for one tick on the next frame (only while paused)."""
        if self.paused:
            self._single_steps += 1

    def advance(self, real_dt: float) -> int:
        """Spend ``real_dt`` seconds of wall time; returns the number of ticks to run now."""
        if self.paused:
            n, self._single_steps = self._single_steps, 0
            return n
        self.accumulator += max(real_dt, 0.0) * self.speed
        # A tolerance so that e.g. 3 x (1/60 s) at x1 with dt = 0.05 gives exactly one tick.
        n = int((self.accumulator + 1e-9) // self.dt)
        if n > self.max_steps_per_frame:
            self.dropped_s += (n - self.max_steps_per_frame) * self.dt
            n = self.max_steps_per_frame
            self.accumulator = 0.0
        else:
            self.accumulator = max(self.accumulator - n * self.dt, 0.0)
        return n
