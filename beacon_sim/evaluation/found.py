"""Whether a filter started lost has found the robot: its estimate near the true pose at
given times of a Monte Carlo run (the corridor's global localization criterion)."""

from __future__ import annotations

import math
from collections.abc import Sequence

from beacon_sim.evaluation.montecarlo import RunOutput

#: The corridor's check times [s]: by 60 s the robot has driven the corridor's length and
#: back once, so a filter that saw the doors can know where it is, and holds it to 90 s.
CORRIDOR_CHECK_S: tuple[float, ...] = (60.0, 70.0, 80.0, 90.0)
#: Within half a cell [m] of the robot: the estimate lies in the 1 m cell centred on it.
FOUND_RADIUS_M = 0.5
#: ... and facing its way: the cosine of the heading error above this (25 degrees).
FOUND_COS = 0.9


def found_at(run: RunOutput, name: str, dt: float, times: Sequence[float] = CORRIDOR_CHECK_S,
             radius: float = FOUND_RADIUS_M, cos_min: float = FOUND_COS) -> bool:
    """Whether filter ``name``'s estimate in ``run`` (steps of ``dt`` [s]) was within
    ``radius`` [m] of the true position and its heading within acos(``cos_min``) of the
    true heading at every one of ``times`` [s]; a failed filter never found it."""
    fr = run.filters[name]
    if fr.failed:
        return False
    for t in times:
        k = round(t / dt)
        if not 1 <= k <= len(fr.err):
            raise ValueError(f"found_at: time {t:g} s is not in the run (0-{len(fr.err) * dt:g} s)")
        e = fr.err[k - 1]
        if not (math.hypot(e[0], e[1]) < radius and math.cos(e[2]) > cos_min):
            return False
    return True
