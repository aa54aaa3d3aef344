"""One headless team run (issue 18): a team scenario, a seed, some team filters; each
robot's accuracy and consistency under each filter, and the team's.

The truth does not depend on the filters. Every team filter runs under the guard of
:class:`~beacon_sim.filters.team_runner.JointRunner`: one that cannot be built, raises,
hangs or returns an unusable estimate is switched off with a message, the others go on, and
it gets no score.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from beacon_sim.core.metrics import anees_band, nees, pose_errors, summary
from beacon_sim.core.team import TeamSimulation, TeamStep
from beacon_sim.core.team_scenario import TeamScenario
from beacon_sim.filters.runner import HEADLESS_STEP_LIMIT_S, FilterTrack, failure_text
from beacon_sim.filters.team_runner import JointRunner, build_team_filters
from beacon_sim.filters.team_specs import build_team_spec, team_filter_name


def anees_verdict(value: float, lo: float, hi: float) -> str:
    """``consistent`` inside the band, ``optimistic`` above it (errors larger than the
    covariance admits), ``pessimistic`` below, ``failed`` when not finite."""
    if not np.isfinite(value):
        return "failed"
    return "optimistic" if value > hi else "pessimistic" if value < lo else "consistent"


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

    @property
    def initial_poses(self) -> np.ndarray:
        """True poses before the first tick, shape (N, 3) (every robot starts exactly at its
        scenario's ``initial_pose``)."""
        return np.array([r.scenario.initial_pose for r in self.team.robots], dtype=float)

    @property
    def controls(self) -> np.ndarray:
        """Each robot's command of each tick, shape (T, N, 2) [m/s, rad/s]."""
        return np.array([[(st.control.v, st.control.omega) for st in s.steps] for s in self.steps],
                        dtype=float).reshape(len(self.steps), len(self.team.robots), 2)

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
        """Per team filter: each robot's figures (core.metrics.summary) with its ANEES verdict
        against the 95 % band of one run's NEES (``anees_band``, 3 dof: consecutive steps are
        correlated, so the band is not narrowed by their number, as in ``eval``), and the
        team's: RMSE over all robots, mean ANEES against the band of N robots' NEES. A failed
        filter has only ``failed`` (the reason and the time): no score."""
        n = len(self.team.robots)
        band, team_band = anees_band(1), anees_band(n)
        filters: dict[str, Any] = {}
        for name, tr in self.tracks.items():
            if tr.failed:
                filters[name] = {"failed": self.failed(name)}
                continue
            if not tr.means:
                filters[name] = {"robots": {}, "no_steps": True, "us_per_step": tr.us_per_step}
                continue
            robots: dict[str, dict[str, Any]] = {}
            for i, r in enumerate(self.team.robots):
                fig = self.robot_summary(name, i)
                robots[r.name] = {**fig, "anees_verdict": anees_verdict(fig["anees"], *band)}
            team_anees = float(np.mean([v["anees"] for v in robots.values()]))
            filters[name] = {
                "robots": robots,
                "team_pos_rmse_m": float(np.sqrt(np.mean([v["pos_rmse_m"] ** 2 for v in robots.values()]))),
                "team_heading_rmse_rad": float(np.sqrt(np.mean([v["heading_rmse_rad"] ** 2
                                                                for v in robots.values()]))),
                "team_anees": team_anees,
                "team_anees_verdict": anees_verdict(team_anees, *team_band),
                "us_per_step": tr.us_per_step,
            }
        return {"scenario": self.team.name, "team": True, "seed": self.seed, "steps": len(self.steps),
                "sim_time_s": len(self.steps) * self.team.dt,
                "robots": [r.name for r in self.team.robots],
                "anees_band": list(band), "team_anees_band": list(team_band),
                "readings": dict(zip([r.name for r in self.team.robots], self.readings(), strict=True)),
                "truth_checksum": self.truth_checksum, "filters": filters}


def run_team_headless(team: TeamScenario, filters: list[str] | None = None, seed: int | None = None,
                      duration: float | None = None,
                      params: dict[str, dict[str, Any]] | None = None,
                      step_limit_s: float | None = HEADLESS_STEP_LIMIT_S,
                      run_limit_s: float | None = None) -> TeamRunResult:
    """Simulate ``duration`` seconds (default: the scenario's) and feed every team filter
    (specs as :func:`build_team_spec`; guarded: see the module docstring). ``params``:
    ``{filter name: {key: value}}``. ``step_limit_s`` [s]: a step that takes longer stops
    the filter; ``run_limit_s`` [s]: so does its filter time in the run passing this (as
    ``eval --time-limit`` and ``grade``'s ``time_limit`` for a single robot)."""
    seed = team.seed if seed is None else seed
    duration = team.duration if duration is None else duration
    specs = list(team.default_filters if filters is None else filters)
    by_name = {team_filter_name(s): s for s in specs}
    built, why = build_team_filters(
        list(by_name), lambda n: build_team_spec(by_name[n], team, (params or {}).get(n), seed),
        step_limit_s)
    runner = JointRunner(built, len(team.robots), step_limit_s)
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
        if run_limit_s is not None:
            for name, tr in runner.tracks.items():
                if not tr.failed and tr.step_ns > run_limit_s * 1e9:
                    runner.fail(name, f"time limit: over {run_limit_s:g} s of filter time in the run",
                                "", step.time)
    return TeamRunResult(team, seed, steps, runner.tracks, sim.truth_checksum, time.perf_counter() - t0)
