"""Keeping a student's filter from spoiling a run: the slow-step warning and the status
line the window and the terminal show for a filter that was switched off or is slow.

The switching off itself happens in :class:`beacon_sim.filters.runner.FilterRunner`: a
filter that raises, returns NaN or infinity, the wrong shapes, or a covariance that is not
symmetric positive semi-definite gets ``track.failed`` (one line) and ``track.traceback``
and is not fed again; the simulation and the other filters go on.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:  # runner imports this module
    from beacon_sim.filters.runner import FilterTrack

#: A filter whose recent steps (predict + update + estimate) average more than this gets
#: ``track.slow_warning`` [ms].
SLOW_STEP_MS = 50.0
#: How many recent steps the average is taken over, and how many are needed before judging.
SLOW_WINDOW = 10
SLOW_MIN_STEPS = 3


def note_step_time(track: FilterTrack, step_ns: int) -> None:
    """Record one step's wall time [ns] on ``track`` and set ``track.slow_warning`` when the
    mean of the last ``SLOW_WINDOW`` steps, leaving out the slowest one, exceeds ``SLOW_STEP_MS``.

    One slow step (a first call that imports or allocates, a garbage collection) does not
    warn; a filter that is slow on every step does after ``SLOW_MIN_STEPS`` steps. The
    warning stays once given (it tells the user the filter cannot keep up in real time).
    """
    recent = track.recent_step_ns
    recent.append(int(step_ns))
    if len(recent) < SLOW_MIN_STEPS:
        return
    mean_ms = (sum(recent) - max(recent)) / (len(recent) - 1) / 1e6
    if mean_ms > SLOW_STEP_MS:
        track.slow_warning = (f"slow: {mean_ms:.0f} ms per step (over {SLOW_STEP_MS:.0f} ms; "
                              f"the simulation cannot run in real time)")


def status_line(track: FilterTrack) -> str | None:
    """What to show next to a filter's name: why it was switched off, or the slow warning."""
    if track.failed:
        return f"{track.name} switched off: {track.failed}"
    if getattr(track, "slow_warning", None):
        return f"{track.name} {track.slow_warning}"
    return None
