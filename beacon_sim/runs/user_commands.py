"""What the commands a user gives during a run do (kidnap, reset, ...), applied the same
way live and on replay, so that a recording reproduces the session bit for bit.

The commands themselves (small JSON-ready dicts) are defined with the recording format,
:data:`beacon_sim.io.recording.COMMAND_KINDS`:
- ``kidnap`` with a ``pose``: teleport the robot there; without: to a random pose drawn from
  the events stream;
- ``reset``: every filter back to the scenario's initial belief, a switched-off one included
  (it runs again unless its reset fails: see :func:`switch_back_on`);
- ``global_reset``: filters that support it get a uniform belief;
- ``toggle``: show / hide a filter (display only: nothing here).
Commands are applied before the simulation step of the tick they are recorded with.

On a run of N robots (:func:`apply_to_run`, live and on replay alike) a team's kidnap names
its robot (``"robot": i``, :data:`beacon_sim.io.recording.TEAM_COMMAND_KINDS`) and a reset
acts on every robot's filters and on the team filters.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from functools import partial

from beacon_sim.core.scenario import Scenario, TeamScenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.core.team import TeamSimulation
from beacon_sim.filters.base import Filter
from beacon_sim.filters.team import initial_beliefs
from beacon_sim.hosting.loading import reset_filter
from beacon_sim.hosting.runner import HEADLESS_STEP_LIMIT_S, NOT_BUILT, call_guarded
from beacon_sim.hosting.team_runner import JointRunner, TeamRunner, team_filter_of
from beacon_sim.io.recording import validate_command


def apply_commands(commands: Iterable[Mapping], sim: Simulation, filters: Mapping[str, Filter],
                   scenario: Scenario, limit_s: float | None = HEADLESS_STEP_LIMIT_S
                   ) -> dict[str, tuple[str, str]]:
    """Apply user commands to the simulation and the filters (``name -> filter``). Returns
    the filters whose ``reset`` failed: ``{name: (why in one line, traceback)}``, for the
    caller to switch off (see :func:`apply_to_filters`)."""
    commands = list(commands)
    for cmd in commands:
        validate_command(cmd)
        if cmd["kind"] == "kidnap":
            sim.request_kidnap(cmd.get("pose"))
    return apply_to_filters(commands, filters, scenario, limit_s)


def apply_to_filters(commands: Iterable[Mapping], filters: Mapping[str, Filter],
                     scenario: Scenario, limit_s: float | None = HEADLESS_STEP_LIMIT_S,
                     cpu: bool = False) -> dict[str, tuple[str, str]]:
    """The filters' part of user commands (resets), also for a filter that catches up over a
    session's history after a hot reload. Each ``reset`` runs under the runner's guard (time
    limit ``limit_s`` [s], of CPU time with ``cpu``; an exception, ``SystemExit`` included,
    is that filter's failure):
    returns ``{name: (why, traceback)}`` of the filters that failed, which get no further
    command."""
    failed: dict[str, tuple[str, str]] = {}
    for cmd in commands:
        kind = cmd["kind"]
        for name, f in filters.items():
            if name in failed:
                continue
            if kind == "reset":
                _, why, tb = call_guarded(partial(reset_filter, f, scenario), limit_s, cpu=cpu)
            elif kind == "global_reset" and getattr(f, "supports_global", False):
                _, why, tb = call_guarded(partial(f.reset, None), limit_s, cpu=cpu)
            else:
                continue
            if why is not None:
                failed[name] = (f"reset: {why}", tb)
    return failed


def apply_to_run(commands: Iterable[Mapping], sim: TeamSimulation | None, run: TeamRunner,
                 limit_s: float | None, time_s: float, cpu: bool = False
                 ) -> dict[str, tuple[str, str]]:
    """User commands on a run of N robots (a single robot is a team of one), before the
    tick's step: a kidnap of the robot it names (robot 0 when it names none); resets of every
    robot's working filters (:func:`apply_to_filters`) and of the team filters
    (:func:`reset_team_filters`). A filter whose reset fails is switched off (on every
    robot, at ``time_s`` [s]); returns those ``{name: (why, traceback)}``. A ``reset``
    first switches back on every filter that was switched off (:func:`switch_back_on`).
    ``cpu``: the limit counts the filter thread's CPU time (the window's). ``sim`` None: the
    filters' part only (a window whose filters run on a worker thread gave the simulation its
    part, :func:`commands_to_sim`, on its own thread)."""
    commands = list(commands)
    if not commands:
        return {}
    if sim is not None:
        commands_to_sim(commands, sim)
    else:
        for cmd in commands:
            validate_command(cmd)
    if any(c["kind"] == "reset" for c in commands):
        switch_back_on(run)
    failed: dict[str, tuple[str, str]] = {}
    for robot, runner in zip(run.team.robots, run.members, strict=True):
        working = {n: t.filter for n, t in runner.tracks.items() if t.filter and not t.failed}
        for name, (why, tb) in apply_to_filters(commands, working, robot.scenario, limit_s,
                                                cpu).items():
            run.fail(name, why, tb, time_s)
            failed[name] = (why, tb)
    if any(c["kind"] in ("reset", "global_reset") for c in commands):
        reset_team_filters(run.joint, run.team, limit_s, time_s, cpu)
    return failed


def commands_to_sim(commands: Iterable[Mapping], sim: TeamSimulation) -> None:
    """The simulation's part of user commands on a run of N robots: a kidnap of the robot it
    names (robot 0 when it names none), requested for the next step."""
    for cmd in commands:
        validate_command(cmd)
        if cmd["kind"] == "kidnap":
            sim.sims[int(cmd.get("robot", 0))].request_kidnap(cmd.get("pose"))


def switch_back_on(run: TeamRunner) -> list[str]:
    """Clear the failure of every filter that was built and then switched off (by a time
    limit, an exception, an unusable estimate), on every robot and among the team filters,
    so that the reset that follows puts it back to the initial belief and it runs again
    (one whose reset fails is switched off again, with that reason). A filter that could not
    be built stays off. Returns the names switched back on."""
    back: list[str] = []
    for runner in run.members:
        for name, tr in runner.tracks.items():
            if tr.failed and tr.failed != NOT_BUILT and tr.filter is not None:
                tr.failed, tr.traceback, tr.failed_time_s = None, "", None
                if name not in back:
                    back.append(name)
    for name, tr in run.joint.tracks.items():
        if tr.failed and team_filter_of(tr) is not None:
            tr.failed, tr.traceback, tr.failed_time_s = None, "", None
            back.append(name)
    return back


def reset_team_filters(runner: JointRunner, team: TeamScenario, limit_s: float | None,
                       time_s: float, cpu: bool = False) -> None:
    """The ``reset`` user command on the team filters: every working one back to the
    scenario's initial beliefs, under the guard (one that fails is switched off), the same
    live and on replay."""
    if not runner.tracks:
        return
    beliefs = initial_beliefs(team)
    for name, tr in runner.tracks.items():
        f = team_filter_of(tr)
        if tr.failed or f is None:
            continue
        _, why, tb = call_guarded(partial(f.reset, beliefs), limit_s, cpu=cpu)
        if why is not None:
            runner.fail(name, f"reset: {why}", tb, time_s)
