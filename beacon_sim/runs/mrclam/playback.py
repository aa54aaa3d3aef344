"""A finished MRCLAM run shown one display tick at a time (:class:`MrclamPlayback`), for the
replay window: lookups only, the filters ran before."""

from __future__ import annotations

import math
from collections.abc import Set
from typing import Any

import numpy as np

from beacon_sim.core.types import Control, EventRecord, Measurement
from beacon_sim.filters.base import Belief, GaussianBelief, LandmarkMap
from beacon_sim.runs.mrclam.map_history import MapHistory
from beacon_sim.runs.mrclam.results import MrclamRun
from beacon_sim.runs.scene import FilterStatus, Trail


class _RecordedMap:
    """A SLAM filter's recorded map, seen as the filter (``landmarks()``) at the time the
    playback shows: the latest map at or before it, an empty one before the first update."""

    def __init__(self, playback: MrclamPlayback, history: MapHistory):
        self.playback, self.history = playback, history

    def landmarks(self) -> LandmarkMap:
        lm = self.history.at(float(self.playback.times[self.playback.k]))
        return lm if lm is not None else LandmarkMap(None, np.zeros((0, 2)), np.zeros((0, 2, 2)))


#: Readings stay drawn this long after their time stamp [s] (they arrive a few per second).
READING_SHOW_S = 0.3


class MrclamPlayback:
    """A finished MRCLAM run seen one display tick of ``scenario.dt`` at a time: a
    :class:`~beacon_sim.runs.scene.Scene` with a timeline, for the replay window.

    The filters ran on the real data first; this only looks the results up: the ground truth
    interpolated to the tick, each filter's latest estimate at or before it, and the landmark
    readings of the last ``READING_SHOW_S`` seconds.
    """

    def __init__(self, run: MrclamRun):
        self.run = run
        self.scenario = sc = run.scenario
        self.names = list(run.tracks)
        self.specs: list[str] = []
        self.seed, self.autopilot = 0, False
        self.params: dict[str, dict[str, Any]] = {}
        self.visible = {n: True for n in self.names}
        self.status = {n: FilterStatus(n) for n in self.names}
        dt = sc.dt
        self.total_ticks = math.floor((run.t_end - run.t_start) / dt + 1e-9)
        self.times = run.t_start + dt * np.arange(self.total_ticks + 1)
        self.truth, _ = run.data.truth_at(self.times)
        # Index of each filter's latest estimate at or before each display tick.
        self.index = {n: np.searchsorted(np.array(tr.times), self.times, side="right") - 1
                      for n, tr in run.tracks.items()}
        ms = run.data.measurements
        self.meas = ms[(ms[:, 0] > run.t_start) & (ms[:, 0] <= run.t_end)]
        self.od = run.data.odometry
        self.shown: dict[str, tuple[np.ndarray, np.ndarray] | None] = {}
        #: The SLAM filters' maps as the window's map layer reads them (``landmarks()`` at
        #: the displayed time); only a ``--slam`` run shown in the window has them.
        self.filters = {n: _RecordedMap(self, h) for n, h in run.map_history.items()}
        self.seek(0)

    # --- time -------------------------------------------------------------------------------
    @property
    def at_end(self) -> bool:
        return self.k >= self.total_ticks

    @property
    def tick_count(self) -> int:
        return self.k

    @property
    def time(self) -> float:
        return float(self.times[self.k] - self.run.t_start)

    @property
    def true_pose(self) -> np.ndarray:
        return self.truth[self.k]

    @property
    def drive_mode(self) -> str:
        return f"MRCLAM {self.run.data.folder.name} robot {self.run.data.robot}"

    def seek(self, tick: int, keep_flips: Set[str] = frozenset()) -> None:
        """Jump to ``tick``; the trails are rebuilt from the start (cheap: lookups only).
        Shown / hidden filters stay as they are (``keep_flips`` is for rebuilt scenes)."""
        self.k = min(max(int(tick), 0), self.total_ticks)
        self.truth_trail = Trail()
        self.trails = {n: Trail() for n in self.names}
        for k in range(self.k):  # the trails up to (not including) the tick shown
            self.truth_trail.add(self.truth[k])
            for n, tr in self.run.tracks.items():
                i = int(self.index[n][k])
                if i >= 0:
                    self.trails[n].add(tr.means[i])
        self._show()

    def tick(self) -> tuple[EventRecord, ...]:
        """One display tick forward; returns its events (none: the data has no kidnaps)."""
        self.k = min(self.k + 1, self.total_ticks)
        self._show()
        return ()

    def _show(self) -> None:
        k, truth = self.k, self.truth[self.k]
        self.truth_trail.add(truth)
        for n, tr in self.run.tracks.items():
            i = int(self.index[n][k])
            st = self.status[n]
            st.failed = tr.failed if i >= len(tr.means) - 1 else None
            self.shown[n] = None
            if i >= 0:
                mean, cov = tr.means[i], tr.covs[i]
                self.shown[n] = (mean, cov)
                self.trails[n].add(mean)
                st.measure(mean, cov, truth)

    # --- what the window reads ----------------------------------------------------------------
    def next_control(self) -> Control:
        """The odometry command in force at the displayed time [m/s, rad/s]."""
        i = int(np.searchsorted(self.od[:, 0], self.times[self.k], side="right")) - 1
        return Control(float(self.od[max(i, 0), 1]), float(self.od[max(i, 0), 2]))

    def readings(self) -> list[Measurement]:
        t = self.times[self.k]
        lo, hi = np.searchsorted(self.meas[:, 0], [t - READING_SHOW_S, t], side="right")
        if hi <= lo:
            return []
        rows = self.meas[lo:hi]
        return [Measurement("mrclam", "range_bearing", rows[:, 2:4].copy(), rows[:, 1].astype(int))]

    def seen_ids(self) -> set[int]:
        return {int(i) for m in self.readings() for i in m.beacon_ids}

    def belief(self, name: str) -> Belief | None:
        est = self.shown.get(name)
        return None if est is None else GaussianBelief(est[0], est[1])

    def estimate(self, name: str) -> tuple[np.ndarray, np.ndarray] | None:
        return self.shown.get(name)

    def marks(self) -> list[tuple[int, str]]:
        return []  # no user commands in a data set

    def trail(self, name: str) -> Trail:
        """Filter ``name``'s estimate trail."""
        return self.trails[name]

    def clear_trails(self) -> None:
        """Forget every trail, keep the current points."""
        self.truth_trail = Trail()
        self.truth_trail.add(self.true_pose)
        self.trails = {n: Trail() for n in self.names}
        for n, est in self.shown.items():
            if est is not None:
                self.trails[n].add(est[0])

    def close(self) -> None:
        """Nothing to close: the run is finished."""
