"""The runners of a MRCLAM run, given each robot's noise: the filters grouped by what they are
told (the Gaussian filters the inflated noise, the robust ones the calibrated noise; with
``slam`` the SLAM filters no map), each group in a
:class:`~beacon_sim.hosting.team_runner.TeamRunner`, fed the data
(:mod:`~beacon_sim.runs.mrclam.feeding`), and their tracks collected into a
:class:`~beacon_sim.runs.mrclam.results.MrclamRun` (:func:`run_calibrated`)."""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from beacon_sim.core.scenario import TeamScenario
from beacon_sim.hosting.runner import HEADLESS_STEP_LIMIT_S, failure_text, guarded_call, validate_estimate
from beacon_sim.hosting.team_runner import TeamRunner, validate_team_estimates
from beacon_sim.hosting.team_specs import check_team_specs, team_filter_name
from beacon_sim.io.mrclam import MrclamData, MrclamError
from beacon_sim.runs.mrclam.associations import AssociationCount
from beacon_sim.runs.mrclam.calibration import Calibration, inflated, told_inflated
from beacon_sim.runs.mrclam.feeding import feed_by_time_stamps, feed_on_a_clock
from beacon_sim.runs.mrclam.map_history import SLAM_MRCLAM_FILTERS, MapHistory, map_withheld
from beacon_sim.runs.mrclam.options import MrclamOptions
from beacon_sim.runs.mrclam.results import MrclamRun, MrclamTrack
from beacon_sim.runs.mrclam.scenario import TEAM_DT, mrclam_team
from beacon_sim.runs.progress import Progress


def run_span(robots: Sequence[MrclamData], duration: float | None) -> tuple[float, float]:
    """The data set times [s] a run covers: from the latest robot's first odometry to the
    earliest robot's last, at most ``duration`` seconds."""
    t_start = max(d.t0 for d in robots)
    t_end = min(float(d.odometry[-1, 0]) for d in robots)
    if duration is not None:
        t_end = min(t_end, t_start + duration)
    return t_start, t_end


def _start_estimates(runner: TeamRunner) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Every working filter's estimate of every robot before the first step (the initial
    belief): name -> (means (N, 3), covs (N, 3, 3)); a filter whose estimate is unusable is
    switched off."""
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for name in runner.names:
        if runner.failed(name):
            continue
        member = runner.is_member(name)
        objs = ([runner.members[i].tracks[name].filter for i in range(runner.n_robots)] if member
                else [runner.joint.tracks[name].filter])
        calls = [getattr(obj, "estimate" if member else "estimates") for obj in objs]
        got = []
        for call in calls:
            raw, why, tb = guarded_call(call, HEADLESS_STEP_LIMIT_S)
            est = (f"estimate(): {why}" if why is not None else validate_estimate(raw) if member
                   else validate_team_estimates(raw, runner.n_robots))
            if isinstance(est, str):
                runner.fail(name, est, tb, 0.0)
                break
            got.append(est)
        else:
            out[name] = ((np.array([g[0] for g in got]), np.array([g[1] for g in got]))
                         if member else got[0])
    return out


def _robot_tracks(runner: TeamRunner, start: dict[str, tuple[np.ndarray, np.ndarray]],
                  times: np.ndarray, ticks: np.ndarray) -> list[dict[str, MrclamTrack]]:
    """Each robot's track of each filter at the recorded ``times`` (the estimate after runner
    tick ``ticks``; a filter that failed keeps the records before it failed)."""
    out: list[dict[str, MrclamTrack]] = [{} for _ in range(runner.n_robots)]
    for name in runner.names:
        _, means, covs = runner.series(name)
        if name in start:
            means = np.concatenate([start[name][0][None], means])
            covs = np.concatenate([start[name][1][None], covs])
        keep = ticks < len(means)
        for i in range(runner.n_robots):
            tr = runner.track(name, i)
            failed = runner.failed(name)
            out[i][name] = MrclamTrack(
                name, tr.filter, times[keep], means[ticks[keep], i], covs[ticks[keep], i],
                us_per_step=tr.us_per_step, joint=not runner.is_member(name), failed=failed,
                failed_time_s=(tr.failed_time_s if tr.failed_time_s is not None else 0.0) if failed else None,
                traceback=tr.traceback)
    return out



def _runners(robots: list[MrclamData], cals: list[Calibration], specs: list[str], team: TeamScenario,
             t_start: float, t_end: float, dt_team: float, params: dict[str, dict[str, Any]] | None,
             options: MrclamOptions) -> tuple[list[TeamRunner], list[str], dict[str, bool]]:
    """The runners of filters ``specs`` on a clock of ``dt_team`` [s], their names in order,
    and per spec whether its map is withheld. The Gaussian filters are told the inflated
    noise, the robust ones the calibrated noise; with ``slam`` the SLAM filters get no map,
    the others keep it. Filters whose names clash across groups run in one runner on the
    inflated noise."""
    from beacon_sim.hosting.loading import filter_names

    correspondence = "unknown" if options.unknown_ids else "known"
    withheld = {s: options.slam and map_withheld(s) for s in specs}
    keys = [(inf, blind) for inf in (True, False) for blind in (False, True)]
    groups = [[s for s in specs if told_inflated(s) == inf and withheld[s] == blind] for inf, blind in keys]
    teams = [mrclam_team(robots, [inflated(c) for c in cals] if inf else cals, t_start, t_end, dt_team,
                         correspondence, map_known=not blind) if group else team
             for (inf, blind), group in zip(keys, groups, strict=True)]
    runners = [TeamRunner(tm, group, 0, params, step_limit_s=HEADLESS_STEP_LIMIT_S)
               for tm, group in zip(teams, groups, strict=True) if group]
    names = filter_names(specs) if team.solo else [team_filter_name(s) for s in specs]
    if sorted(n for r in runners for n in r.names) != sorted(names):  # a name primed across groups
        if options.slam and len(set(withheld.values())) > 1:
            raise MrclamError("--slam: give SLAM filters and map-given filters different names "
                              f"(got {', '.join(specs)})")
        blind_team = mrclam_team(robots, [inflated(c) for c in cals], t_start, t_end, dt_team,
                                 correspondence, map_known=False) if any(withheld.values()) else team
        runners = [TeamRunner(blind_team, specs, 0, params, step_limit_s=HEADLESS_STEP_LIMIT_S)]
    return runners, names, withheld


def run_calibrated(robots: list[MrclamData], cals: list[Calibration], filters: list[str] | None,
                   t_start: float, t_end: float, params: dict[str, dict[str, Any]] | None,
                   options: MrclamOptions, progress: bool = False) -> MrclamRun:
    """Filters ``filters`` (None: the team's defaults, or ``SLAM_MRCLAM_FILTERS`` with
    ``slam``) over ``robots`` from ``t_start`` to ``t_end`` [s], robot ``i`` told noise
    ``cals[i]`` (inflated for the Gaussian filters). One robot without ``options.dt``: fed by
    time stamp; otherwise on a clock of ``options.dt`` (default ``TEAM_DT``). ``progress``:
    the seconds of data fed, on stderr (:mod:`beacon_sim.runs.progress`: a bar on a terminal,
    plain periodic lines in a log); it changes nothing in the results."""
    from beacon_sim.hosting.loading import check_param_names

    options.check(len(robots))
    correspondence = "unknown" if options.unknown_ids else "known"
    dt_team = TEAM_DT if options.dt is None else options.dt
    team = mrclam_team(robots, [inflated(c) for c in cals], t_start, t_end, dt_team, correspondence)
    specs = list((SLAM_MRCLAM_FILTERS if options.slam else team.default_filters) if filters is None
                 else filters)
    if team.solo:
        check_param_names(params, specs)
    else:
        check_team_specs(specs, team, params)
    runners, names, withheld = _runners(robots, cals, specs, team, t_start, t_end, dt_team, params,
                                         options)
    starts = [_start_estimates(r) for r in runners]
    bar = Progress(max(1, math.ceil(t_end - t_start)), "mrclam", progress, unit="s of data")
    t0 = time.perf_counter()
    scores: dict[str, AssociationCount] | None = {} if options.unknown_ids else None
    maps: dict[str, MapHistory] | None = {} if options.record_maps else None
    if team.solo and options.dt is None:
        times, ticks, updates, readings = feed_by_time_stamps(runners, robots[0], cals[0], t_start,
                                                              t_end, scores, maps, bar)
    else:
        times, ticks, updates, readings = feed_on_a_clock(runners, robots, cals, t_start, t_end,
                                                          dt_team, bar)
    wall = time.perf_counter() - t0
    failed = {}
    tracks: list[dict[str, MrclamTrack]] = [{} for _ in robots]
    for runner, start in zip(runners, starts, strict=True):
        for name in runner.names:
            if runner.failed(name):
                failed[name] = failure_text(runner.track(name)) or str(runner.failed(name))
        for mine, theirs in zip(tracks, _robot_tracks(runner, start, times, ticks), strict=True):
            mine.update(theirs)
    tracks = [{n: t[n] for n in names} for t in tracks]  # in the order the filters were named
    given = {n: not withheld[s] for n, s in zip(names, specs, strict=True)}
    if options.graph:
        from beacon_sim.runs.mrclam.graph_slam import GRAPH_NAME, graph_slam_track

        if GRAPH_NAME in tracks[0]:
            raise MrclamError(f"--graph adds a track named {GRAPH_NAME}: name no filter so")
        tracks[0][GRAPH_NAME], history = graph_slam_track(robots[0], cals[0], t_start, t_end)
        given[GRAPH_NAME] = False
        if maps is not None:
            maps[GRAPH_NAME] = history
        names = [*names, GRAPH_NAME]
    return MrclamRun(robots, team, cals, tracks, t_start, t_end, updates, readings, wall,
                     {n: failed[n] for n in names if n in failed}, options.unknown_ids,
                     {n: scores[n] for n in names if scores and n in scores}, options.slam, given,
                     {n: maps[n] for n in names if maps and n in maps})
