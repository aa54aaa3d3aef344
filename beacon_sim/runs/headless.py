"""One headless run: a scenario, a seed, some filters; returns the figures ``run`` prints.

Used by ``beacon-sim run`` and the tests. The simulation and the filters see exactly the
same steps; the result is the same whatever filters run (the truth does not depend on them).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from beacon_sim.core.metrics import summary
from beacon_sim.core.scenario import Scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.core.types import Step
from beacon_sim.filters.loading import build_filters
from beacon_sim.filters.runner import HEADLESS_STEP_LIMIT_S, FilterRunner
from beacon_sim.runs.progress import Progress

#: The figures of a run that a failed filter does not get (null in JSON, empty in CSV).
ACCURACY_KEYS = ("pos_rmse_m", "heading_rmse_rad", "mse_x", "mse_y", "mse_theta", "anees")


@dataclass
class RunResult:
    """What a headless run produced: the truth, each filter's track, and counters."""

    scenario: Scenario
    seed: int
    steps: list[Step]
    runner: FilterRunner
    wall_s: float
    sim_wall_s: float
    truth_checksum: str
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def truth(self) -> np.ndarray:
        """True poses after each step, shape (T, 3)."""
        return np.array([s.true_pose for s in self.steps]).reshape(-1, 3)

    def distance(self) -> float:
        """Length of the true path [m], kidnap jumps excluded."""
        d = 0.0
        prev = np.array(self.scenario.initial_pose)
        for s in self.steps:
            if not s.kidnapped:
                d += float(np.hypot(*(s.true_pose[:2] - prev[:2])))
            prev = s.true_pose
        return d

    def measurement_counts(self) -> dict[str, int]:
        """Readings per sensor (beacon sightings for beacon sensors, fixes for fix sensors)."""
        counts = {s.name: 0 for s in self.scenario.sensors}
        for s in self.steps:
            for m in s.measurements:
                counts[m.sensor] += len(m)
        return counts

    def filter_summary(self) -> dict[str, dict[str, Any]]:
        out: dict[str, dict[str, Any]] = {}
        truth_by_tick = {s.tick: s.true_pose for s in self.steps}
        for name, tr in self.runner.tracks.items():
            row: dict[str, Any] = {}
            if tr.failed:  # no score for a filter that failed: its figures would flatter it
                row.update(dict.fromkeys(ACCURACY_KEYS))
            elif tr.means:
                truths = np.array([truth_by_tick[t] for t in tr.ticks])
                row.update(summary(np.array(tr.means), np.array(tr.covs), truths))
            row["us_per_step"] = tr.us_per_step
            if tr.failed:
                row["failed"] = tr.failed
                row["failed_time_s"] = tr.failed_time_s
            if tr.slow_warning:
                row["slow_warning"] = tr.slow_warning
            out[name] = row
        return out

    def as_json(self) -> dict[str, Any]:
        return {
            "scenario": self.scenario.name,
            "seed": self.seed,
            "steps": len(self.steps),
            "sim_time_s": round(len(self.steps) * self.scenario.dt, 9),
            "distance_m": self.distance(),
            "measurements": self.measurement_counts(),
            "events": [{"kind": e.kind, "tick": e.tick, "time": e.time, "detail": e.detail}
                       for s in self.steps for e in s.events],
            "truth_checksum": self.truth_checksum,
            "steps_per_s": len(self.steps) / self.sim_wall_s if self.sim_wall_s else None,
            "filters": self.filter_summary(),
        }


def run_headless(scenario: Scenario, filters: list[str] | None = None, seed: int | None = None,
                 duration: float | None = None,
                 params: dict[str, dict[str, Any]] | None = None,
                 progress: bool = False) -> RunResult:
    """Simulate ``duration`` seconds (default: the scenario's) and feed every filter.

    ``filters`` are filter specs (built-in names, ``pkg.mod:Class``, ``file.py:Class``);
    None runs the scenario's ``default_filters``. ``progress``: a progress bar on stderr
    once the run has taken a second.
    """
    seed = scenario.seed if seed is None else seed
    duration = scenario.duration if duration is None else duration
    specs = list(scenario.default_filters if filters is None else filters)
    built, broken = build_filters(specs, scenario, seed, params)
    runner = FilterRunner(built, step_limit_s=HEADLESS_STEP_LIMIT_S)
    for name, (message, tb) in broken.items():
        runner.tracks[name].failed, runner.tracks[name].traceback = message, tb
    sim = Simulation(scenario, seed)
    n = round(duration / scenario.dt)
    bar = Progress(n, f"run {scenario.name}", progress, unit="ticks")
    steps = []
    t0 = time.perf_counter()
    sim_ns = 0
    for _ in range(n):
        a = time.perf_counter_ns()
        step = sim.step()
        sim_ns += time.perf_counter_ns() - a
        steps.append(step)
        runner.feed(step)
        bar.advance()
    wall = time.perf_counter() - t0
    return RunResult(scenario, seed, steps, runner, wall, sim_ns / 1e9, sim.truth_checksum)
