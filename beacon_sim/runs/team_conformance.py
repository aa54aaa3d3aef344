"""``beacon-sim check`` for a student's own team filter (a class with ``estimates()``,
docs/multi-robot.md "Your own team filter"): it loads, has the four methods, builds with a
TeamContext, runs a team scenario under the team guard with a usable estimate of every
robot on every tick, and gives the same bits twice for the same seed."""

from __future__ import annotations

from functools import partial

import numpy as np

from beacon_sim.core.team_scenario import TeamScenario
from beacon_sim.filters.conformance import CheckResult
from beacon_sim.filters.runner import failure_text
from beacon_sim.runs.team import run_team_headless

#: The methods a team filter implements (filters/team.TeamFilter).
TEAM_METHODS = ("reset", "predict", "update", "estimates")
#: Simulated time each run of the check lasts [s].
CHECK_DURATION_S = 10.0


def run_team_checks(spec: str, cls: type, team: TeamScenario) -> list[CheckResult]:
    """The checks of team filter class ``cls`` (named ``spec``) on ``team``."""
    results = [CheckResult("loads", True, f"{cls.__module__}.{cls.__qualname__} (a team filter)")]
    missing = [m for m in TEAM_METHODS if not callable(getattr(cls, m, None))]
    if missing:
        results.append(CheckResult("interface", False, f"missing: {', '.join(missing)}",
                                   "implement reset(initial), predict(controls, dt), "
                                   "update(measurements) and estimates() (docs/multi-robot.md)"))
        return results
    results.append(CheckResult("interface", True, ", ".join(TEAM_METHODS)))
    runs = [partial(run_team_headless, team, [spec], seed=seed, duration=CHECK_DURATION_S)
            for seed in (0, 0)]
    first = runs[0]()
    name = next(iter(first.tracks))
    why = failure_text(first.tracks[name])
    if why:
        results.append(CheckResult("runs", False, why,
                                   "fix the error above (beacon-sim run "
                                   f"{team.name} --filter {spec} shows the traceback's last line)"))
        return results
    ticks = len(first.steps)
    results.append(CheckResult("runs", True, f"{ticks} ticks of {team.name}, {len(team.robots)} "
                               "robots, a usable estimate of every robot on every tick"))
    second = runs[1]()
    same = (np.array_equal(np.array(first.tracks[name].means), np.array(second.tracks[name].means))
            and np.array_equal(np.array(first.tracks[name].covs), np.array(second.tracks[name].covs)))
    results.append(CheckResult(
        "deterministic", same, "same seed, same bits" if same else "two runs with seed 0 differ",
        "draw random numbers only from ctx.members[i].ctx.rng (seeded), never np.random or time"))
    return results
