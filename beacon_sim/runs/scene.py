"""What a window shows after each tick, whatever drives it: a live session, a replay, a
finished MRCLAM run played back.

:class:`Scene` is the protocol the renderer and the panel read; :class:`FilterStatus` holds
one filter's figures for the panel (the HUD's error and NEES come from here); :class:`Trail`
is a path drawn behind a robot or an estimate. No pygame here.
"""

from __future__ import annotations

import math
from collections.abc import Set as AbstractSet
from dataclasses import dataclass
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

    def measure(self, mean, cov, truth) -> None:
        """The errors [m, rad], the sigmas [m, rad] and NEES of the estimate ``(mean, cov)``
        against ``truth``."""
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

    @property
    def nees_out_of_band(self) -> bool:
        return math.isfinite(self.nees) and not NEES_BAND[0] <= self.nees <= NEES_BAND[1]


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
