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
#: The band for a window worth ``n`` independent values (index n, 1..NEES_WINDOW_SAMPLES).
#: While the robot stands still its errors hardly change (a filter at rest, or one averaging
#: readings of a pose that does not move), so a run of ticks at rest counts as ONE value of
#: the window, not one per 2 s: a minute's pause in a lecture put a badge on a consistent
#: EKF on 14 of 20 seeds of ``default`` with the band for ten (:meth:`FilterStatus.measure`).
NEES_WINDOW_BANDS = [(math.nan, math.nan)] + [
    anees_band(n, dof=3, confidence=NEES_WINDOW_CONFIDENCE) for n in range(1, NEES_WINDOW_SAMPLES + 1)]
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
    #: How many independent NEES values the window is worth (NEES_WINDOW_SAMPLES while the
    #: robot moves; fewer when it stood still in it); NaN until the window is full.
    nees_samples: float = math.nan
    _recent: deque[float] = field(default_factory=deque, repr=False)
    _verdict: str | None = field(default=None, repr=False)
    _hold: int = field(default=0, repr=False)  # ticks the verdict is still held
    # The window's ticks as runs [at rest?, ticks], oldest first; the ticks that moved and
    # the sum of the squared lengths of the runs at rest (kept as ticks come and go).
    _runs: deque[list] = field(default_factory=deque, repr=False)
    _moved: int = field(default=0, repr=False)
    _rest_sq: int = field(default=0, repr=False)
    _last_truth: tuple | None = field(default=None, repr=False)

    def clear_window(self) -> None:
        """Forget the NEES window (a reset: the filter starts again from its initial belief)."""
        self._recent.clear()
        self._runs.clear()
        self._moved = self._rest_sq = 0
        self._last_truth = None
        self.nees_mean = self.nees_samples = math.nan
        self._verdict, self._hold = None, 0

    def _count(self, at_rest: bool, step: int) -> None:
        """A tick into the window (``step`` 1, at its new end) or out of it (-1, its start)."""
        runs = self._runs
        if step > 0:
            if runs and runs[-1][0] == at_rest:
                runs[-1][1] += 1
            else:
                runs.append([at_rest, 1])
            run = runs[-1]
        else:
            run = runs[0]
            run[1] -= 1
        if at_rest:
            n = run[1]
            self._rest_sq += n * n - (n - step) * (n - step)
        else:
            self._moved += step
        if step < 0 and run[1] == 0:
            runs.popleft()

    def _window_samples(self, k: int) -> float:
        """The independent values a full window of ``k`` ticks is worth: Kish's effective
        size ``1 / sum w^2`` of its parts, each tick that moved a 1/k share of one of
        NEES_WINDOW_SAMPLES values of k / NEES_WINDOW_SAMPLES ticks, each run of ticks at
        rest one value of its length's share (all moving: 10; all at rest: 1)."""
        block = k / NEES_WINDOW_SAMPLES
        return k * k / (self._moved * block + self._rest_sq)

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
        here = (float(truth[0]), float(truth[1]), float(truth[2]))
        at_rest = here == self._last_truth  # the robot did not move since the last estimate
        self._last_truth = here
        self._count(at_rest, 1)
        k = max(round(NEES_WINDOW_S / dt), 1)
        while len(recent) > k:
            recent.popleft()
            self._count(self._runs[0][0], -1)
        full = len(recent) == k
        m = self.nees_mean = sum(recent) / k if full else math.nan
        n = self.nees_samples = self._window_samples(k) if full else math.nan
        lo, hi = NEES_WINDOW_BANDS[max(1, min(NEES_WINDOW_SAMPLES, int(n + 1e-9)))] if full \
            else (math.nan, math.nan)
        now = None if math.isnan(m) else ("high" if m > hi else "low" if m < lo else None)
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
