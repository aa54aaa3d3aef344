"""``beacon-sim mrclam DIR --robot N`` on screen: ground truth, landmarks, readings and the
filters' estimates of a finished :func:`beacon_sim.mrclam.run_mrclam`, played back with the
replay window's timeline.

The filters ran on the real data first (odometry and readings interleaved by time stamp);
this view only looks the results up at display ticks of ``scenario.dt`` seconds after the
start: the ground truth interpolated to the tick, each filter's latest estimate at or before
it, and the landmark readings of the last ``READING_SHOW_S`` seconds (rays of the measured
range and bearing from the true pose). The adapter below gives the renderer and the panel
what they read from a live :class:`~beacon_sim.app.session.Session`.
"""

from __future__ import annotations

import math
import os
import sys
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np
import pygame

from beacon_sim.app.replay import ReplayApp
from beacon_sim.app.session import FilterStatus, Trail
from beacon_sim.core.types import Control, Measurement
from beacon_sim.filters.base import GaussianBelief

#: Readings stay drawn this long after their time stamp [s] (they arrive a few per second).
READING_SHOW_S = 0.3


@dataclass
class _Shown:
    """The estimate of one filter at the displayed tick, shaped like a runner's track."""

    name: str
    failed: str | None
    means: list = field(default_factory=list)
    covs: list = field(default_factory=list)
    slow_warning: str | None = None

    @property
    def filter(self):
        return self  # the renderer asks ``track.filter.belief()``

    def belief(self):
        return GaussianBelief(self.means[-1], self.covs[-1]) if self.means else None

    def estimate(self):
        return self.means[-1], self.covs[-1]


class MrclamPlayback:
    """A finished MRCLAM run seen one display tick at a time (what the window reads)."""

    def __init__(self, run):
        self.run = run
        self.scenario = sc = run.scenario
        self.names = list(run.tracks)
        self.specs: list[str] = []
        self.seed, self.params, self.autopilot = 0, {}, False
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
        self.mismatch = None
        self.runner = SimpleNamespace(tracks={})
        self.seek(0)

    # --- time -------------------------------------------------------------------------------
    @property
    def at_end(self) -> bool:
        return self.k >= self.total_ticks

    @property
    def sim(self):
        return SimpleNamespace(tick=self.k, time=float(self.times[self.k] - self.run.t_start),
                               pose=self.truth[self.k])

    @property
    def drive_mode(self) -> str:
        return f"MRCLAM {self.run.data.folder.name} robot {self.run.data.robot}"

    def seek(self, tick: int) -> None:
        """Jump to ``tick``; the trails are rebuilt from the start (cheap: lookups only)."""
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

    def tick(self):
        self.k = min(self.k + 1, self.total_ticks)
        self._show()
        return SimpleNamespace(events=())

    def _show(self) -> None:
        k, truth = self.k, self.truth[self.k]
        self.truth_trail.add(truth)
        tracks = {}
        for n, tr in self.run.tracks.items():
            i = int(self.index[n][k])
            shown = _Shown(n, tr.failed if i >= len(tr.means) - 1 else None)
            st = self.status[n]
            st.failed = shown.failed
            if i >= 0:
                mean, cov = tr.means[i], tr.covs[i]
                shown.means, shown.covs = [mean], [cov]
                self.trails[n].add(mean)
                st.measure(mean, cov, truth)
            tracks[n] = shown
        self.runner.tracks = tracks

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

    def command(self, cmd: dict) -> None:  # the replay window handles toggles itself
        pass

    def close(self) -> None:
        pass


class MrclamApp(ReplayApp):
    """The replay window (timeline, keys, help) over an :class:`MrclamPlayback`."""

    def __init__(self, run, size=(1280, 800), scripted: bool = False):
        self.replay_of = None
        self.specs, self.params = [], {}
        self.reported = True  # no checksum to report
        self._open(MrclamPlayback(run), size, scripted)

    def _make_watchers(self, interval: float) -> dict:
        return {}  # the estimates are computed already: nothing to hot-reload

    def seek(self, tick: int) -> None:
        self.session.seek(tick)
        self.clock.accumulator = 0.0

    def marks(self) -> list:
        return []


def show_mrclam(run, args) -> int:
    """The window over a finished MRCLAM run, until quit (or ``args.frames`` frames of
    1/60 s when the parser offers ``--frames``; ``args.screenshot`` saves the last frame)."""
    frames = getattr(args, "frames", None)
    os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
    try:
        app = MrclamApp(run, scripted=frames is not None)
    except pygame.error as exc:  # no display: the table above is the result
        print(f"note: cannot open a window ({exc}); results above are headless", file=sys.stderr)
        return 0
    try:
        app.run(frames)
        if getattr(args, "screenshot", None):
            app.save_screenshot(args.screenshot)
    finally:
        app.close()
    print(f"mrclam: shown up to t = {app.session.sim.time:.1f} s of "
          f"{run.t_end - run.t_start:.1f} s", file=sys.stderr)
    return 0


__all__ = ["MrclamApp", "MrclamPlayback", "show_mrclam"]
