"""How fast the window really goes: frames per second, and the speed factor the simulation
delivers (under load the clock drops ticks, so "x8" may be less in truth).
"""

from __future__ import annotations

import numpy as np


def fps_of(frame_times: np.ndarray) -> float:
    """Frames per second from recent frame durations [s]."""
    if not len(frame_times):
        return 0.0
    m = float(np.mean(frame_times))
    return 1.0 / m if m > 0 else 0.0
