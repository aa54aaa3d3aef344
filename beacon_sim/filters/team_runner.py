"""Feeds each team tick to any number of team filters, side by side on the same data: the
team form of :class:`~beacon_sim.filters.runner.FilterRunner`, with the same guard.

A team filter that raises (``SystemExit`` and a time-out included) or returns anything
but one usable ``(mean (3,), cov (3, 3))`` per robot is switched off with a one-line
message; the simulation and the other team filters go on. Each robot's estimate goes
through :func:`~beacon_sim.filters.runner.validate_estimate`, the one guard every front
end uses. A failed filter keeps the estimates it gave before it failed and gets no score.

A track's ``means[k]`` is (N, 3) [m, m, rad] and ``covs[k]`` (N, 3, 3): every robot's
estimate after tick ``ticks[k]``, world frame, in team order.
"""

from __future__ import annotations

import time
import traceback
from collections.abc import Callable, Mapping, Sequence
from functools import partial
from typing import Any, cast

import numpy as np

from beacon_sim.core.types import Control, Measurement
from beacon_sim.filters.runner import (
    NOT_BUILT,
    FilterTimeout,
    FilterTrack,
    bounded_track,
    exit_text,
    is_filter_failure,
    note_step_time,
    one_line,
    run_filter_code,
    time_limit,
    validate_estimate,
)
from beacon_sim.filters.team import TeamFilter


def team_filter_of(track: FilterTrack) -> TeamFilter | None:
    """The team filter a team runner's track holds (None: not built). ``FilterTrack`` is
    shared with single robots and types its object as a ``Filter``; a
    :class:`TeamFilterRunner` only ever puts team filters in it."""
    return cast("TeamFilter | None", track.filter)


def validate_team_estimates(est: object, n_robots: int) -> tuple[np.ndarray, np.ndarray] | str:
    """What a team filter's ``estimates()`` returned, checked: ``(means (N, 3), covs (N, 3, 3))``
    as fresh float arrays, or one line saying why it is unusable (naming the robot)."""
    if not isinstance(est, list | tuple) or len(est) != n_robots:
        got = f"{len(est)} entries" if isinstance(est, list | tuple) else type(est).__name__
        return f"estimates() returned {got}, expected one (mean, cov) pair per robot ({n_robots})"
    means, covs = np.empty((n_robots, 3)), np.empty((n_robots, 3, 3))
    for i, e in enumerate(est):
        r = validate_estimate(e)
        if isinstance(r, str):
            return f"robot {i + 1}: {r}"
        means[i], covs[i] = r
    return means, covs


def build_team_filters(names: Sequence[str], build: Callable[[str], Any],
                       limit_s: float | None) -> tuple[dict[str, Any], dict[str, str]]:
    """Each named team filter built (and reset) by ``build(name)`` under a time limit:
    (name -> filter or None, name -> why it could not be built)."""
    built: dict[str, Any] = {}
    why: dict[str, str] = {}
    for name in names:
        try:
            built[name] = run_filter_code(partial(build, name), limit_s, "construction")
        except Exception as exc:  # FilterExit included: SystemExit, time-out
            built[name] = None
            why[name] = one_line(exc)
    return built, why


class TeamFilterRunner:
    """Runs several team filters on the same ticks (see the module docstring).

    ``filters``: name -> a built, reset team filter, or None for one that could not be
    built (its track starts switched off). ``step_limit_s``: a tick (predict + update +
    estimates) longer than this [s] stops the filter. ``keep``: keep only the last
    ``keep`` estimates (the window); None keeps them all (headless runs).
    """

    def __init__(self, filters: Mapping[str, Any], n_robots: int,
                 step_limit_s: float | None = None, keep: int | None = None):
        self.n_robots = n_robots
        self.step_limit_s = step_limit_s
        self.tracks: dict[str, FilterTrack] = {
            name: bounded_track(name, f, keep, failed=None if f is not None else NOT_BUILT)
            for name, f in filters.items()}

    def fail(self, name: str, reason: str, tb: str = "", time_s: float | None = None) -> None:
        """Switch ``name`` off with ``reason`` (one line) at simulated time ``time_s`` [s]."""
        track = self.tracks[name]
        if track.failed and track.failed != NOT_BUILT:
            return
        track.failed, track.traceback, track.failed_time_s = reason, tb, time_s

    def feed(self, tick: int, time_s: float, controls: Sequence[Control], dt: float,
             readings: Sequence[Sequence[Measurement]]) -> None:
        """Predict every working team filter with each robot's command, update it with each
        robot's readings (beacon and robot readings), record its checked estimates."""
        limit = self.step_limit_s
        for track in self.tracks.values():
            f = team_filter_of(track)
            if track.failed or f is None:
                continue
            t0 = time.perf_counter_ns()
            try:
                try:
                    with time_limit(limit):
                        f.predict(controls, dt)
                        f.update(readings)
                        est = f.estimates()
                finally:
                    elapsed = time.perf_counter_ns() - t0
            except FilterTimeout:
                self.fail(track.name, f"time limit: a step took over {limit:g} s",
                          traceback.format_exc(), time_s)
                continue
            except Exception as exc:
                self.fail(track.name, one_line(exc), traceback.format_exc(), time_s)
                continue
            except (SystemExit, KeyboardInterrupt) as exc:
                if not is_filter_failure(exc):
                    raise  # the user's Ctrl-C
                self.fail(track.name, exit_text(exc), traceback.format_exc(), time_s)
                continue
            track.step_ns += elapsed
            track.steps += 1
            note_step_time(track, elapsed)
            checked = validate_team_estimates(est, self.n_robots)
            if isinstance(checked, str):
                self.fail(track.name, checked, "", time_s)
                continue
            track.means.append(checked[0])
            track.covs.append(checked[1])
            track.ticks.append(tick)
