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
from functools import partial
from typing import Any

import numpy as np

from beacon_sim.core.metrics import anees_band, nees, pose_errors, summary
from beacon_sim.core.team import TeamSimulation, TeamStep
from beacon_sim.core.team_scenario import TeamScenario
from beacon_sim.filters.base import FilterError
from beacon_sim.filters.loading import (
    BUILD_LIMIT_S,
    build_filter,
    filter_display_name,
    load_filter_class,
    split_label,
)
from beacon_sim.filters.runner import HEADLESS_STEP_LIMIT_S, FilterTrack, failure_text, run_filter_code
from beacon_sim.filters.team import (
    TEAM_FILTERS,
    IndependentTeam,
    TeamFilter,
    build_team_filter,
    initial_beliefs,
    team_context,
)
from beacon_sim.filters.team_runner import TeamFilterRunner, build_team_filters

#: ``independent:F``: every robot's own single-robot filter F (a built-in name, pkg.mod:Class
#: or file.py:Class), beacon readings only.
MEMBER_PREFIX = "independent:"


def team_filter_name(spec: str) -> str:
    """The name a team filter spec is shown and ``--set`` under: its label, else the spec
    (a student's team filter class ``my_team.py:MyTeam``: its class name, ``MyTeam``)."""
    label, body = split_label(spec)
    if label:
        return label
    if body in TEAM_FILTERS or body.startswith(MEMBER_PREFIX):
        return body
    return filter_display_name(body)


def build_team_class(spec: str, team: TeamScenario, params: dict[str, Any] | None,
                     seed: int) -> TeamFilter:
    """A student's own team filter: a class (``file.py:Class``, ``pkg.mod:Class``) built with
    a :class:`~beacon_sim.filters.team.TeamContext` and reset to the scenario's initial
    beliefs. A single-robot filter class given here is a FilterError that says to use
    ``independent:``."""
    _, body = split_label(spec)
    cls = load_filter_class(body)
    if not callable(getattr(cls, "estimates", None)):
        raise FilterError(f"{body}: {getattr(cls, '__name__', cls)!s} is not a team filter (it has no "
                          f"estimates()); to run a single-robot filter on every robot use "
                          f"independent:{body}")
    name = team_filter_name(spec)
    merged = {**team.filter_params.get(name, {}), **(params or {})}
    f = cls(team_context(team, name, merged, seed))
    f.reset(initial_beliefs(team))
    return f


def build_team_spec(spec: str, team: TeamScenario, params: dict[str, Any] | None = None,
                    seed: int | None = None) -> TeamFilter:
    """A team filter from a spec: a name of ``filters.team.TEAM_FILTERS``; a student's team
    filter class (``my_team.py:MyTeam``, see :func:`build_team_class`); or ``independent:F``
    (optionally labelled ``alice=independent:./alice.py:MyEkf``): every robot's own
    single-robot filter F, built as ``run`` builds it for that robot's scenario (its
    parameters: the scenario's ``[filters.F]`` then ``params``), wrapped in
    :class:`~beacon_sim.filters.team.IndependentTeam`. Raises FilterError for a name or
    parameter that cannot work; a filter's own failing code raises what it raises."""
    name = team_filter_name(spec)
    _, body = split_label(spec)
    if not body.startswith(MEMBER_PREFIX):
        if body not in TEAM_FILTERS and ":" in body:
            return build_team_class(spec, team, params, team.seed if seed is None else seed)
        return build_team_filter(body, team, params, seed)
    member = body[len(MEMBER_PREFIX):]
    if not member:
        raise FilterError(f"{spec}: expected independent:FILTER, e.g. independent:ukf")
    seed = team.seed if seed is None else seed
    members = iter([build_filter(member, r.scenario, seed, name=f"{name}/{r.id}", params=params)
                    for r in team.robots])
    f = IndependentTeam(team_context(team, name, None, seed), member=lambda _ctx: next(members))
    f.reset(initial_beliefs(team))
    return f


def check_team_specs(specs: list[str], team: TeamScenario,
                     params: dict[str, dict[str, Any]] | None = None,
                     limit_s: float = BUILD_LIMIT_S) -> None:
    """Raise FilterError (one line, exit status 2 on the command line) for a team filter
    name, a ``--set`` name or a parameter that cannot work, before anything runs. A
    filter whose own code fails when built (raising, exiting, or still building after
    ``limit_s`` [s]) is left to the run (it fails there, no score)."""
    names = [team_filter_name(s) for s in specs]
    if len(set(names)) < len(names):
        raise FilterError(f"a team filter named twice in {', '.join(names)}")
    for name in params or {}:
        if name not in names:
            raise FilterError(f"--set {name}.*: no team filter {name!r} in this run; the filters are "
                              f"{', '.join(names)}")
    for spec in specs:
        _, body = split_label(spec)
        if not body.startswith(MEMBER_PREFIX) and body not in TEAM_FILTERS and ":" not in body:
            raise FilterError(f"no team filter named {body!r}; choose one of "
                              f"{', '.join(TEAM_FILTERS)}, independent:FILTER or a team filter "
                              "class (file.py:Class)")
        try:
            run_filter_code(partial(build_team_spec, spec, team,
                                    (params or {}).get(team_filter_name(spec)), team.seed),
                            limit_s, "construction")
        except FilterError:
            raise
        except Exception:  # the filter's own code: a failed filter in the run, no score
            pass


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
        if run_limit_s is not None:
            for name, tr in runner.tracks.items():
                if not tr.failed and tr.step_ns > run_limit_s * 1e9:
                    runner.fail(name, f"time limit: over {run_limit_s:g} s of filter time in the run",
                                "", step.time)
    return TeamRunResult(team, seed, steps, runner.tracks, sim.truth_checksum, time.perf_counter() - t0)
