"""One headless team run (issue 18): a team scenario, a seed, some team filters; each
robot's accuracy and consistency under each filter, and the team's.

The truth does not depend on the filters. Every team filter runs under the guard of
:class:`~beacon_sim.filters.team_runner.TeamFilterRunner`: one that cannot be built, raises,
hangs or returns an unusable estimate is switched off with a message, the others go on, and
it gets no score.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from beacon_sim.core.metrics import nees, pose_errors, summary
from beacon_sim.core.team import TeamSimulation, TeamStep
from beacon_sim.core.team_scenario import TeamScenario
from beacon_sim.filters.runner import HEADLESS_STEP_LIMIT_S, FilterTrack, failure_text
from beacon_sim.filters.team import build_team_filter
from beacon_sim.filters.team_runner import TeamFilterRunner, build_team_filters


@dataclass
class TeamRunResult:
    team: TeamScenario
    seed: int
    steps: list[TeamStep]
    tracks: dict[str, FilterTrack]
    truth_checksum: str
    wall_s: float

    def failed(self, name: str) -> str | None:
        """Why team filter ``name`` was switched off (with the time), or None."""
        return failure_text(self.tracks[name])

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
            if tr.failed:
                filters[name] = {"failed": self.failed(name)}
                continue
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
                      params: dict[str, dict[str, Any]] | None = None,
                      step_limit_s: float | None = HEADLESS_STEP_LIMIT_S) -> TeamRunResult:
    """Simulate ``duration`` seconds (default: the scenario's) and feed every team filter
    (guarded: see the module docstring)."""
    seed = team.seed if seed is None else seed
    duration = team.duration if duration is None else duration
    names = list(team.default_filters if filters is None else filters)
    built, why = build_team_filters(
        names, lambda n: build_team_filter(n, team, (params or {}).get(n), seed), step_limit_s)
    runner = TeamFilterRunner(built, len(team.robots), step_limit_s)
    for name, reason in why.items():
        runner.tracks[name].failed = f"could not be built: {reason}"
    sim = TeamSimulation(team, seed)
    steps = []
    t0 = time.perf_counter()
    for _ in range(round(duration / team.dt)):
        step = sim.step()
        steps.append(step)
        runner.feed(step.tick, step.time, [s.control for s in step.steps], step.dt,
                    [step.measurements(i) for i in range(len(step.steps))])
    return TeamRunResult(team, seed, steps, runner.tracks, sim.truth_checksum, time.perf_counter() - t0)
