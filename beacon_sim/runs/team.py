"""One headless team run (issue 18): a team scenario, a seed, some team filters; each
robot's accuracy and consistency under each filter, and the team's.

The truth does not depend on the filters. Team filters are the built-in ones of
filters/team.py (not guarded by the single-robot FilterRunner: a failure raises).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from beacon_sim.core.metrics import nees, pose_errors, summary
from beacon_sim.core.team import TeamSimulation, TeamStep
from beacon_sim.core.team_scenario import TeamScenario
from beacon_sim.filters.team import TeamFilter, build_team_filter


@dataclass
class TeamTrack:
    """One team filter's estimates after every tick: means (T, N, 3), covs (T, N, 3, 3)."""

    means: list[np.ndarray] = field(default_factory=list)
    covs: list[np.ndarray] = field(default_factory=list)
    ns: int = 0

    @property
    def us_per_step(self) -> float:
        return self.ns / 1e3 / max(len(self.means), 1)


@dataclass
class TeamRunResult:
    team: TeamScenario
    seed: int
    steps: list[TeamStep]
    tracks: dict[str, TeamTrack]
    truth_checksum: str
    wall_s: float

    @property
    def truth(self) -> np.ndarray:
        """True poses, shape (T, N, 3)."""
        return np.array([s.true_poses for s in self.steps])

    def robot_summary(self, name: str, i: int) -> dict[str, float]:
        """Robot i's figures under filter ``name`` (core.metrics.summary: RMSE, ANEES)."""
        tr = self.tracks[name]
        return summary(np.array(tr.means)[:, i], np.array(tr.covs)[:, i], self.truth[:, i])

    def nees(self, name: str, i: int) -> np.ndarray:
        """Robot i's NEES per tick (3 dof) under filter ``name``."""
        tr = self.tracks[name]
        return nees(pose_errors(np.array(tr.means)[:, i], self.truth[:, i]), np.array(tr.covs)[:, i])

    def readings(self) -> list[dict[str, int]]:
        """Per robot: beacon readings and robot readings over the run."""
        out = []
        for i in range(len(self.team.robots)):
            out.append({"beacon": sum(len(m) for s in self.steps for m in s.steps[i].measurements),
                        "robot": sum(len(m) for s in self.steps for m in s.robot_readings[i])})
        return out

    def as_json(self) -> dict[str, Any]:
        filters: dict[str, Any] = {}
        for name, tr in self.tracks.items():
            robots = {r.name: self.robot_summary(name, i) for i, r in enumerate(self.team.robots)}
            filters[name] = {
                "robots": robots,
                "team_pos_rmse_m": float(np.sqrt(np.mean([v["pos_rmse_m"] ** 2 for v in robots.values()]))),
                "team_anees": float(np.mean([v["anees"] for v in robots.values()])),
                "us_per_step": tr.us_per_step,
            }
        return {"scenario": self.team.name, "seed": self.seed, "steps": len(self.steps),
                "robots": [r.name for r in self.team.robots],
                "readings": dict(zip([r.name for r in self.team.robots], self.readings(), strict=True)),
                "truth_checksum": self.truth_checksum, "filters": filters}


def run_team_headless(team: TeamScenario, filters: list[str] | None = None, seed: int | None = None,
                      duration: float | None = None,
                      params: dict[str, dict[str, Any]] | None = None) -> TeamRunResult:
    """Simulate ``duration`` seconds (default: the scenario's) and feed every team filter."""
    seed = team.seed if seed is None else seed
    duration = team.duration if duration is None else duration
    names = list(team.default_filters if filters is None else filters)
    built: dict[str, TeamFilter] = {n: build_team_filter(n, team, (params or {}).get(n), seed) for n in names}
    tracks = {n: TeamTrack() for n in names}
    sim = TeamSimulation(team, seed)
    steps = []
    t0 = time.perf_counter()
    for _ in range(round(duration / team.dt)):
        step = sim.step()
        steps.append(step)
        controls = [s.control for s in step.steps]
        readings = [step.measurements(i) for i in range(len(step.steps))]
        for n, f in built.items():
            a = time.perf_counter_ns()
            f.predict(controls, step.dt)
            f.update(readings)
            est = f.estimates()
            tracks[n].ns += time.perf_counter_ns() - a
            tracks[n].means.append(np.array([m for m, _ in est]))
            tracks[n].covs.append(np.array([c for _, c in est]))
    return TeamRunResult(team, seed, steps, tracks, sim.truth_checksum, time.perf_counter() - t0)
