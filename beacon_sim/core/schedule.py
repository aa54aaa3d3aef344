"""The tick schedule of a scenario: on which ticks each sensor reads, and which ticks a
blackout or a noise burst covers. One object that the simulation, the PCRB, the live bound
and the sessions all read, so they agree on every tick.

Tick ``k`` (1-based) is the step from time ``(k - 1) dt`` to ``k dt``; a sensor of period
``p`` [s] reads on the ticks ``k`` with ``k % round(p / dt) == 0`` (the scenario loader
only accepts whole multiples of dt).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Protocol

from beacon_sim.core.events import Blackout, NoiseBurst, active_ticks
from beacon_sim.core.scenario import Scenario


class _Periodic(Protocol):
    @property
    def name(self) -> str: ...

    @property
    def period(self) -> float: ...


def period_ticks(period: float, dt: float) -> int:
    """A sensor period [s] in ticks of ``dt`` [s]: ``round(period / dt)``, at least 1."""
    return max(1, round(period / dt))


@dataclass(frozen=True)
class TickSchedule:
    """``every``: sensor name -> its period in ticks; ``blackouts`` and ``bursts``: tick ->
    the blackouts / noise bursts in force on it (in the scenario's order)."""

    every: Mapping[str, int]
    blackouts: Mapping[int, tuple[Blackout, ...]]
    bursts: Mapping[int, tuple[NoiseBurst, ...]]

    def due(self, sensor: str, tick: int) -> bool:
        """True when ``sensor`` takes a reading on ``tick`` (blacked out or not)."""
        return tick % self.every[sensor] == 0

    def blacked_out(self, sensor: str, tick: int) -> bool:
        """True when a blackout covers ``sensor`` on ``tick``."""
        return any(b.covers(sensor) for b in self.blackouts.get(tick, ()))

    def reads(self, sensor: str, tick: int) -> bool:
        """True when ``sensor`` is due on ``tick`` and no blackout covers it."""
        return self.due(sensor, tick) and not self.blacked_out(sensor, tick)

    def bursts_at(self, tick: int) -> tuple[NoiseBurst, ...]:
        """The noise bursts in force on ``tick``."""
        return self.bursts.get(tick, ())


def tick_schedule(scenario: Scenario, more_sensors: Iterable[_Periodic] = ()) -> TickSchedule:
    """The schedule of ``scenario``'s sensors (and ``more_sensors``, e.g. a team robot's
    robot sensors: anything with a ``name`` and a ``period`` [s]) and of its events."""
    dt = scenario.dt
    blackouts: dict[int, list[Blackout]] = {}
    bursts: dict[int, list[NoiseBurst]] = {}
    for ev in scenario.events:
        if isinstance(ev, Blackout):
            for k in active_ticks(ev, dt):
                blackouts.setdefault(k, []).append(ev)
        elif isinstance(ev, NoiseBurst):
            for k in active_ticks(ev, dt):
                bursts.setdefault(k, []).append(ev)
    every = {s.name: period_ticks(s.period, dt) for s in (*scenario.sensors, *more_sensors)}
    return TickSchedule(every, {k: tuple(v) for k, v in blackouts.items()},
                        {k: tuple(v) for k, v in bursts.items()})


__all__ = ["TickSchedule", "period_ticks", "tick_schedule"]
