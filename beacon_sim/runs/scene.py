"""What a window shows after each tick, whatever drives it: a live session, a replay, a
finished MRCLAM run played back.

:class:`Scene` is the protocol the renderer and the panel read; :class:`FilterStatus` holds
one filter's figures for the panel (the HUD's error and NEES come from here); :class:`Trail`
is a path drawn behind a robot or an estimate. No pygame here.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Set as AbstractSet
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from beacon_sim.core.angles import diff
from beacon_sim.core.metrics import anees_band
from beacon_sim.core.scenario import Scenario
from beacon_sim.core.types import Control, Measurement
from beacon_sim.filters.base import Belief

#: Single-sample NEES band: the 2.5 % and 97.5 % quantiles of chi-square with 3 degrees of
#: freedom, from the same function as every other consistency band; outside it the HUD
#: highlights the value.
NEES_BAND = anees_band(1, dof=3)

#: The panel's NEES verdict is on the mean NEES over the last ``NEES_WINDOW_S`` simulated
#: seconds (none before the window is full, nor after a reset until it is full again): one
#: tick's NEES of a consistent filter is out of its 95 % band 5 % of the time, a blinking
#: badge on a healthy filter.
NEES_WINDOW_S = 20.0
#: The window's mean is judged as the mean of this many independent NEES values (one per
#: 2 s: a filter's errors on consecutive ticks are far from independent), at 99 %: on a
#: consistent EKF over an hour of driving on ``default`` it is out of its band about twice
#: (``benchmarks/bench_nees_alarm.py``; per-tick flags: about 700 times).
NEES_WINDOW_SAMPLES = 10
NEES_WINDOW_CONFIDENCE = 0.99
NEES_WINDOW_BAND = anees_band(NEES_WINDOW_SAMPLES, dof=3, confidence=NEES_WINDOW_CONFIDENCE)
#: A verdict stays this long [s] after the mean was last outside its band: a mean that
#: hovers at the band's edge does not make the badge blink.
NEES_HOLD_S = 5.0


class Trail:
    """A polyline in metres with breaks (kidnaps, resets), thinned to ``min_step`` metres
    and capped at ``max_points`` (the oldest half is dropped when full)."""

    def __init__(self, min_step: float = 0.02, max_points: int = 6000):
        self.min_step = min_step
        self.max_points = max_points
        self.clear()

    def clear(self) -> None:
        """Forget every point (the same thinning and cap)."""
        self.points = np.full((self.max_points, 2), np.nan)
        self.n = 0
        self._last = np.array([np.nan, np.nan])

    def add(self, xy) -> None:
        xy = np.asarray(xy, dtype=float)[:2]
        if self.n and np.isfinite(self._last[0]) and math.hypot(*(xy - self._last)) < self.min_step:
            return
        self._append(xy)
        self._last = xy

    def brk(self) -> None:
        """Start a new piece: the next point is not joined to the previous one."""
        if self.n and np.isfinite(self.points[self.n - 1, 0]):
            self._append(np.array([np.nan, np.nan]))
        self._last = np.array([np.nan, np.nan])

    def _append(self, xy) -> None:
        if self.n == self.max_points:
            half = self.max_points // 2
            self.points[:half] = self.points[half:]
            self.points[half:] = np.nan
            self.n = half
        self.points[self.n] = xy
        self.n += 1

    def pieces(self) -> list[np.ndarray]:
        """The unbroken pieces, each shape (k, 2) [m] with k >= 2."""
        pts = self.points[: self.n]
        if not len(pts):
            return []
        cut = np.flatnonzero(np.isnan(pts[:, 0]))
        out = []
        for seg in np.split(pts, cut):
            seg = seg[np.isfinite(seg[:, 0])]
            if len(seg) >= 2:
                out.append(seg)
        return out


@dataclass
class FilterStatus:
    """What the HUD shows for one filter after the latest tick."""

    name: str
    pos_err: float = math.nan  # [m]
    heading_err: float = math.nan  # [rad]
    nees: float = math.nan
    pos_sigma: float = math.nan  # [m] sqrt of the largest eigenvalue of the x-y covariance
    heading_sigma: float = math.nan  # [rad]
    failed: str | None = None
    warning: str | None = None  # e.g. slower than the time budget
    #: The mean NEES over the last NEES_WINDOW_S seconds; NaN until the window is full.
    nees_mean: float = math.nan
    _recent: deque[float] = field(default_factory=deque, repr=False)
    _verdict: str | None = field(default=None, repr=False)
    _hold: int = field(default=0, repr=False)  # ticks the verdict is still held

    def clear_window(self) -> None:
        """Forget the NEES window (a reset: the filter starts again from its initial belief)."""
        self._recent.clear()
        self.nees_mean = math.nan
        self._verdict, self._hold = None, 0

    def measure(self, mean, cov, truth, dt: float = 0.05) -> None:
        """The errors [m, rad], the sigmas [m, rad] and NEES of the estimate ``(mean, cov)``
        against ``truth``, and the mean NEES of the window (estimates ``dt`` [s] apart)."""
        cov = np.asarray(cov, dtype=float)
        try:
            self.pos_sigma = math.sqrt(max(float(np.linalg.eigvalsh(cov[:2, :2])[-1]), 0.0))
        except np.linalg.LinAlgError:
            self.pos_sigma = math.nan
        self.heading_sigma = math.sqrt(max(float(cov[2, 2]), 0.0))
        e = np.array([mean[0] - truth[0], mean[1] - truth[1], diff(mean[2], truth[2])])
        self.pos_err = math.hypot(e[0], e[1])
        self.heading_err = float(e[2])
        try:
            self.nees = float(e @ np.linalg.solve(cov, e))
        except np.linalg.LinAlgError:
            self.nees = math.inf
        recent = self._recent
        recent.append(self.nees if not math.isnan(self.nees) else math.inf)
        k = max(round(NEES_WINDOW_S / dt), 1)
        while len(recent) > k:
            recent.popleft()
        m = self.nees_mean = sum(recent) / k if len(recent) == k else math.nan
        now = None if math.isnan(m) else ("high" if m > NEES_WINDOW_BAND[1] else
                                          "low" if m < NEES_WINDOW_BAND[0] else None)
        if now is not None:
            self._verdict, self._hold = now, round(NEES_HOLD_S / dt)
        elif self._hold > 0:
            self._hold -= 1
        else:
            self._verdict = None

    @property
    def nees_verdict(self) -> str | None:
        """``"high"``: the window's mean NEES is above its band (the error is larger than the
        filter claims: overconfident); ``"low"``: below it (the filter claims more
        uncertainty than its error shows); None: within (for ``NEES_HOLD_S`` at least), or
        the window is not full yet."""
        return self._verdict

    @property
    def nees_out_of_band(self) -> bool:
        """Whether the window's mean NEES is outside its band (:attr:`nees_verdict`)."""
        return self.nees_verdict is not None


class Scene(Protocol):
    """What the renderer and the panel read after each tick (units: m, rad, s; world frame).
    A team's scene (a live or replayed :class:`~beacon_sim.runs.live.Session` with
    ``n_robots`` > 1) also gives every robot's poses, estimates and readings; the window
    reads them through ``n_robots``."""

    names: list[str]  # the filters, in display order
    visible: dict[str, bool]
    status: dict[str, FilterStatus]

    @property
    def scenario(self) -> Scenario:
        """The (driven) robot's scenario."""
        ...

    @property
    def truth_trail(self) -> Trail:
        """The (driven) robot's true path."""
        ...

    def trail(self, name: str) -> Trail:
        """The (driven) robot's estimate trail under filter ``name``."""
        ...

    def clear_trails(self) -> None:
        """Forget every trail, keep the current points."""
        ...

    @property
    def tick_count(self) -> int:
        """Ticks run so far: the tick shown."""
        ...

    @property
    def time(self) -> float:
        """Seconds since the start of the run."""
        ...

    @property
    def true_pose(self) -> np.ndarray:
        """The true pose (3,) [m, m, rad] at the shown tick."""
        ...

    @property
    def drive_mode(self) -> str:
        """Who drives, in words for the panel."""
        ...

    def next_control(self) -> Control:
        """The command [m/s, rad/s] in force."""
        ...

    def readings(self) -> list[Measurement]:
        """The readings to draw (the latest of each sensor)."""
        ...

    def seen_ids(self) -> set[int]: ...

    def belief(self, name: str) -> Belief | None:
        """The filter's belief to draw (may raise: a student's code)."""
        ...

    def estimate(self, name: str) -> tuple[np.ndarray, np.ndarray] | None:
        """The filter's latest (mean (3,), covariance (3, 3)), or None."""
        ...


class Timeline(Protocol):
    """A run played back on a timeline (a replay, a finished MRCLAM run): what the replay
    window's timeline reads and drives."""

    @property
    def total_ticks(self) -> int: ...

    @property
    def at_end(self) -> bool: ...

    def seek(self, tick: int, keep_flips: AbstractSet[str] = frozenset()) -> None:
        """Show the run at ``tick`` (``keep_flips``: filters shown / hidden by the user)."""
        ...

    def marks(self) -> list[tuple[int, str]]:
        """(tick, kind) of the recorded user commands."""
        ...
