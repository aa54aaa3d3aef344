"""How often the panel's NEES badge comes on for a filter: the windowed verdict of
:class:`~beacon_sim.runs.scene.FilterStatus` over a headless run, against the per-tick
band it replaced, and over a standstill (what ``benchmarks/bench_nees_alarm.py`` prints and
the tests bound)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from beacon_sim.core.scenario import Scenario
from beacon_sim.runs.headless import run_headless
from beacon_sim.runs.scene import NEES_BAND, FilterStatus


@dataclass(frozen=True)
class AlarmCount:
    """Badges over a run: ``windowed`` times the window's verdict came on (``high`` and
    ``low`` of them), ``per_tick`` times one tick's NEES left its 95 % band (the old badge),
    over ``hours`` of simulated time."""

    windowed: int
    high: int
    low: int
    per_tick: int
    hours: float

    @property
    def per_hour(self) -> float:
        return self.windowed / self.hours


def count_alarms(scenario: Scenario, filter_spec: str, seed: int, duration_s: float) -> AlarmCount:
    """Run ``filter_spec`` on ``scenario`` (seed, ``duration_s`` [s] of simulated time) and
    count how often each badge came on (an alarm is a tick whose verdict differs from the
    previous tick's and is not None)."""
    res = run_headless(scenario, [filter_spec], seed=seed, duration=duration_s)
    track = res.track(res.names[0])
    truth = res.true_poses[:, 0, :] if res.true_poses.ndim == 3 else res.true_poses
    truth = truth[-len(track.means):]
    st = FilterStatus(filter_spec)
    prev, prev_tick = None, False
    high = low = per_tick = 0
    for mean, cov, true in zip(track.means, track.covs, truth, strict=True):
        st.measure(mean, cov, true, scenario.dt)
        verdict = st.nees_verdict
        if verdict is not None and verdict != prev:
            high += verdict == "high"
            low += verdict == "low"
        prev = verdict
        out = bool(np.isfinite(st.nees)) and not NEES_BAND[0] <= st.nees <= NEES_BAND[1]
        per_tick += out and not prev_tick
        prev_tick = out
    return AlarmCount(high + low, high, low, per_tick, duration_s / 3600.0)


@dataclass(frozen=True)
class StandstillBadges:
    """The badge over a standstill: ``flagged`` seeds of ``seeds`` showed it at some tick
    after the window first filled, ``high`` and ``low`` ticks of ``ticks`` judged."""

    flagged: int
    seeds: int
    high: int
    low: int
    ticks: int


def count_standstill_badges(scenario: Scenario, filter_spec: str, seeds, duration_s: float,
                            params: dict | None = None) -> StandstillBadges:
    """The window's session (``runs.live.Session``) with the robot standing still from t = 0
    (the keyboard never pressed) for ``duration_s`` [s] of simulated time, once per seed of
    ``seeds``: how often the panel's NEES badge came on for ``filter_spec`` (with
    ``params`` as ``--set`` gives them) once its window was full. A pause in a lecture."""
    from beacon_sim.runs.live import Session  # (the window's session: the panel's figures)

    seeds = list(seeds)
    flagged = high = low = ticks = 0
    for seed in seeds:
        s = Session(scenario, [filter_spec], seed, params or {})
        name, hit = s.names[0], False
        for _ in range(round(duration_s / scenario.dt)):
            s.tick()
            st = s.status[name]
            if np.isnan(st.nees_mean):
                continue
            ticks += 1
            v = st.nees_verdict
            high += v == "high"
            low += v == "low"
            hit |= v is not None
        flagged += hit
    return StandstillBadges(flagged, len(seeds), high, low, ticks)
