"""Hot reload in a live session (``runs/live.Session`` is made of :class:`FilterSwapping`): a
new filter object swapped in under a running filter's name, caught up over the session's
history (the same steps and resets the others had) when that is quick, else started from the
initial belief; with the filters on a worker thread, between two of its ticks.
"""

from __future__ import annotations

import time
from typing import Any

from beacon_sim.core.scenario import Scenario
from beacon_sim.core.team import TeamStep
from beacon_sim.filters.base import Filter
from beacon_sim.hosting.loading import reset_filter
from beacon_sim.hosting.runner import (
    WINDOW_STEP_LIMIT_S,
    FilterRunner,
    FilterTrack,
    bounded_track,
    status_line,
)
from beacon_sim.hosting.team_runner import TeamRunner
from beacon_sim.runs.scene import FilterStatus, Trail
from beacon_sim.runs.user_commands import apply_to_filters

#: A reloaded filter catches up over the session's history when that takes at most this
#: long [s] (estimated from its first steps); otherwise it restarts from the initial belief.
CATCH_UP_BUDGET_S = 1.5
#: The session keeps every tick for a catch-up up to this much simulated time [s] (about
#: 0.7 kB a tick and robot: 20 minutes at 20 Hz is 17 MB); later reloads start from the
#: initial belief.
HISTORY_S = 1200.0
#: Estimates a window's session keeps per filter (the screen needs the latest; a rebuilt
#: trail at most this many points, the trail's own cap): memory does not grow with time.
KEEP_ESTIMATES = 6000


class FilterSwapping:
    """Hot reload of a session's filter (see the module docstring)."""

    # What this reads and changes, all set up by the session (live.Session).
    n_robots: int
    filters_run: TeamRunner
    steps: list[TeamStep]
    commands: dict[int, list[dict]]
    sim: Any
    trails: dict[str, list[Trail]]
    status: dict[str, FilterStatus]
    robot_status: dict[str, list[FilterStatus]]
    last_step: TeamStep | None
    team: Any
    names: list[str]
    worker: Any
    _state: Any

    @property
    def scenario(self) -> Scenario:
        raise NotImplementedError

    @property
    def runner(self) -> FilterRunner:
        raise NotImplementedError

    def settle(self, each: Any = None) -> int:
        raise NotImplementedError

    def _keep_priors(self) -> None:
        raise NotImplementedError

    def _sync_status(self, name: str) -> None:
        raise NotImplementedError

    def _filter_tick(self, tick: int, drawing: bool = False) -> Any:
        raise NotImplementedError

    def replace_filter(self, name: str, flt: Filter, budget_s: float = CATCH_UP_BUDGET_S) -> str:
        """Swap in a new filter object under ``name`` (hot reload), same colour; one robot's
        only (a team's filter copies are not hot reloaded: ValueError).

        The new filter is run over every tick of the session so far (the same Steps and the
        same resets the others had), so it appears where it would be had it run from the
        start. When that would take longer than ``budget_s`` [s] (judged on its first
        steps) it starts from the initial belief instead. Returns what happened, in words.
        """
        if self.n_robots != 1 or not self.filters_run.is_member(name):
            raise ValueError("hot reload replaces a single robot's filter")
        if self.worker is not None:  # between two ticks: the worker's ticks finished and shown
            self.settle()
            try:
                self.worker, worker = None, self.worker
                return self.replace_filter(name, flt, budget_s)
            finally:
                self.worker = worker
                self._state = self._filter_tick(self.sim.tick, drawing=True)
                for n in self.names:
                    self._sync_status(n)
        if len(self.steps) < self.sim.tick:  # the history was not kept this far
            reset_filter(flt, self.scenario)
            self._install(name, bounded_track(name, flt, KEEP_ESTIMATES))
            return (f"{name} reloaded from the initial belief (the session keeps "
                    f"{HISTORY_S / 60:.0f} minutes of history to catch up over)")
        catch_up = FilterRunner({name: flt}, step_limit_s=WINDOW_STEP_LIMIT_S, keep=KEEP_ESTIMATES,
                                cpu_limits=True)
        t0 = time.perf_counter()
        for i, team_step in enumerate(self.steps):
            step = team_step.steps[0]
            cmds = self.commands.get(step.tick)
            if cmds and not catch_up.tracks[name].failed:
                for _, (why, tb) in apply_to_filters(cmds, {name: flt}, self.scenario,
                                                     WINDOW_STEP_LIMIT_S, cpu=True).items():
                    catch_up.fail(name, why, tb, step.time - step.dt)
            catch_up.feed(step)
            elapsed = time.perf_counter() - t0
            if catch_up.tracks[name].failed:
                break
            if i in (19, 199) and elapsed * len(self.steps) / (i + 1) > budget_s:
                projected = elapsed * len(self.steps) / (i + 1)
                reset_filter(flt, self.scenario)
                self._install(name, bounded_track(name, flt, KEEP_ESTIMATES))
                return (f"{name} reloaded from the initial belief: catching up over "
                        f"{len(self.steps)} ticks would take about {projected:.0f} s")
        self._install(name, catch_up.tracks[name])
        if not self.steps:
            return f"{name} reloaded"
        return (f"{name} reloaded and run over the {len(self.steps)} ticks so far "
                f"({time.perf_counter() - t0:.2f} s)")

    def _install(self, name: str, track: FilterTrack) -> None:
        """Put ``track`` in the runner under ``name``; rebuild its trail and status from it."""
        self.runner.tracks[name] = track
        trail = self.trails[name][0] = Trail()
        for mean in track.means:
            trail.add(mean)
        st = self.status[name] = FilterStatus(name)
        self.robot_status[name] = [st]
        st.failed, st.warning = track.failed, status_line(track)
        last = self.last_step
        if track.means and last is not None and track.ticks[-1] == last.tick:
            st.measure(track.means[-1], track.covs[-1], last.steps[0].true_pose, self.team.dt)
        self.runner.priors.pop(name, None)
        self._keep_priors()


__all__ = ["CATCH_UP_BUDGET_S", "HISTORY_S", "KEEP_ESTIMATES", "FilterSwapping"]
