"""The filters of a run over N robots, fed tick by tick (a single robot is a team of one).

:class:`TeamRunner` is what every front end (window, headless run, replay, MRCLAM) runs:
each single-robot filter spec runs one copy per robot, each copy in that robot's
:class:`~beacon_sim.hosting.runner.FilterRunner` (the single-robot guard, the step view, hot
reload); each team filter spec runs once over the joint state in a :class:`JointRunner`.
With one robot and single-robot specs it *is* one FilterRunner (``members[0]``), built and
fed exactly as a single-robot run always was.

:class:`JointRunner` feeds each team tick to any number of team filters, side by side on the
same data: the team form of :class:`~beacon_sim.hosting.runner.FilterRunner`, with the same
guard.

A team filter that raises (``SystemExit`` and a time-out included) or returns anything
but one usable ``(mean (3,), cov (3, 3))`` per robot is switched off with a one-line
message; the simulation and the other team filters go on. Each robot's estimate goes
through :func:`~beacon_sim.hosting.runner.validate_estimate`, the one guard every front
end uses. A failed filter keeps the estimates it gave before it failed and gets no score.

A track's ``means[k]`` is (N, 3) [m, m, rad] and ``covs[k]`` (N, 3, 3): every robot's
estimate after tick ``ticks[k]``, world frame, in team order.
"""

from __future__ import annotations

import time
import traceback
from collections.abc import Callable, Mapping, Sequence
from functools import partial
from typing import Any, cast

import numpy as np

from beacon_sim.core.scenario import TeamScenario
from beacon_sim.core.team import TeamStep
from beacon_sim.core.types import Control, Measurement
from beacon_sim.filters.base import FilterError
from beacon_sim.filters.team import TeamFilter
from beacon_sim.hosting.loading import BUILD_LIMIT_S, build_filter, build_filters, filter_names
from beacon_sim.hosting.runner import (
    NOT_BUILT,
    FilterRunner,
    FilterTimeout,
    FilterTrack,
    bounded_track,
    exit_text,
    is_filter_failure,
    note_step_time,
    one_line,
    run_filter_code,
    time_limit,
    validate_estimate,
)
from beacon_sim.hosting.team_specs import build_team_spec, member_spec, team_filter_name


def team_filter_of(track: FilterTrack) -> TeamFilter | None:
    """The team filter a team runner's track holds (None: not built). ``FilterTrack`` is
    shared with single robots and types its object as a ``Filter``; a
    :class:`JointRunner` only ever puts team filters in it."""
    return cast("TeamFilter | None", track.filter)


def validate_team_estimates(est: object, n_robots: int) -> tuple[np.ndarray, np.ndarray] | str:
    """What a team filter's ``estimates()`` returned, checked: ``(means (N, 3), covs (N, 3, 3))``
    as fresh float arrays, or one line saying why it is unusable (naming the robot)."""
    if not isinstance(est, list | tuple) or len(est) != n_robots:
        got = f"{len(est)} entries" if isinstance(est, list | tuple) else type(est).__name__
        return f"estimates() returned {got}, expected one (mean, cov) pair per robot ({n_robots})"
    means, covs = np.empty((n_robots, 3)), np.empty((n_robots, 3, 3))
    for i, e in enumerate(est):
        r = validate_estimate(e)
        if isinstance(r, str):
            return f"robot {i + 1}: {r}"
        means[i], covs[i] = r
    return means, covs


def build_team_filters(names: Sequence[str], build: Callable[[str], Any],
                       limit_s: float | None) -> tuple[dict[str, Any], dict[str, str]]:
    """Each named team filter built (and reset) by ``build(name)`` under a time limit:
    (name -> filter or None, name -> why it could not be built)."""
    built: dict[str, Any] = {}
    why: dict[str, str] = {}
    for name in names:
        try:
            built[name] = run_filter_code(partial(build, name), limit_s, "construction")
        except Exception as exc:  # FilterExit included: SystemExit, time-out
            built[name] = None
            why[name] = one_line(exc)
    return built, why


class JointRunner:
    """Runs several team filters on the same ticks (see the module docstring).

    ``filters``: name -> a built, reset team filter, or None for one that could not be
    built (its track starts switched off). ``step_limit_s``: a tick (predict + update +
    estimates) longer than this [s] stops the filter. ``keep``: keep only the last
    ``keep`` estimates (the window); None keeps them all (headless runs).
    """

    def __init__(self, filters: Mapping[str, Any], n_robots: int,
                 step_limit_s: float | None = None, keep: int | None = None,
                 cpu_limits: bool = False):
        self.n_robots = n_robots
        self.step_limit_s = step_limit_s
        self.cpu_limits = cpu_limits  # the step limit in the filter thread's CPU time
        self.slow_by_cpu = False  # the slow warning on the thread's CPU time (runner.FilterRunner)
        self.tracks: dict[str, FilterTrack] = {
            name: bounded_track(name, f, keep, failed=None if f is not None else NOT_BUILT)
            for name, f in filters.items()}

    def fail(self, name: str, reason: str, tb: str = "", time_s: float | None = None) -> None:
        """Switch ``name`` off with ``reason`` (one line) at simulated time ``time_s`` [s]."""
        track = self.tracks[name]
        if track.failed and track.failed != NOT_BUILT:
            return
        track.failed, track.traceback, track.failed_time_s = reason, tb, time_s

    def feed(self, tick: int, time_s: float, controls: Sequence[Control], dt: float,
             readings: Sequence[Sequence[Measurement]]) -> None:
        """Predict every working team filter with each robot's command, update it with each
        robot's readings (beacon and robot readings), record its checked estimates."""
        limit = self.step_limit_s
        for track in self.tracks.values():
            f = team_filter_of(track)
            if track.failed or f is None:
                continue
            t0 = time.perf_counter_ns()
            cpu0 = time.thread_time_ns() if self.slow_by_cpu else 0
            try:
                try:
                    with time_limit(limit, self.cpu_limits):
                        f.predict(controls, dt)
                        f.update(readings)
                        est = f.estimates()
                finally:
                    elapsed = time.perf_counter_ns() - t0
            except FilterTimeout:
                self.fail(track.name, f"time limit: a step took over {limit:g} s",
                          traceback.format_exc(), time_s)
                continue
            except Exception as exc:
                self.fail(track.name, one_line(exc), traceback.format_exc(), time_s)
                continue
            except (SystemExit, KeyboardInterrupt) as exc:
                if not is_filter_failure(exc):
                    raise  # the user's Ctrl-C
                self.fail(track.name, exit_text(exc), traceback.format_exc(), time_s)
                continue
            track.step_ns += elapsed
            track.steps += 1
            note_step_time(track, time.thread_time_ns() - cpu0 if self.slow_by_cpu else elapsed)
            checked = validate_team_estimates(est, self.n_robots)
            if isinstance(checked, str):
                self.fail(track.name, checked, "", time_s)
                continue
            track.means.append(checked[0])
            track.covs.append(checked[1])
            track.ticks.append(tick)


class TeamRunner:
    """Every filter of a run over ``team``'s robots, by name, in the order given.

    ``specs``: on a team of one (``team.solo``), single-robot filter specs, named by
    :func:`~beacon_sim.hosting.loading.filter_names`, exactly as a single-robot run; on a
    team, the specs of :mod:`~beacon_sim.hosting.team_specs` (``independent:F`` runs F on
    every robot, a team filter once). ``params``: ``{name: {key: value}}``.

    ``members[i]`` is robot i's FilterRunner of the single-robot filters (keyed by the run's
    filter names); ``joint`` the JointRunner of the team filters. A copy of a single-robot
    filter that fails on one robot switches the filter off on every robot (a filter is
    scored on the whole team or not at all). ``step_limit_s``, ``run_limit_s``, ``keep`` and
    ``cpu_limits`` are FilterRunner's; ``build_limit_s`` bounds each construction [s];
    ``secret`` keys the filters' random streams (None: the public key; ``grade``'s secret).
    """

    def __init__(self, team: TeamScenario, specs: Sequence[str], seed: int,
                 params: Mapping[str, Mapping[str, Any]] | None = None, *,
                 step_limit_s: float | None = None, run_limit_s: float | None = None,
                 keep: int | None = None, cpu_limits: bool = False,
                 build_limit_s: float = BUILD_LIMIT_S, secret: bytes | None = None):
        self.team = team
        self.n_robots = team.n_robots
        settings: dict[str, dict[str, Any]] = {k: dict(v) for k, v in (params or {}).items()}
        specs = list(specs)
        member_built: list[dict[str, Any]] = [{} for _ in team.robots]
        broken: dict[str, tuple[str, str]] = {}
        joint_specs: dict[str, str] = {}
        if team.solo:
            self.names = filter_names(specs)
            built, broken = build_filters(specs, team.robots[0].scenario, seed, settings,
                                          limit_s=build_limit_s, secret=secret)
            member_built[0] = dict(built)
        else:
            self.names = [team_filter_name(s) for s in specs]
            for name, spec in zip(self.names, specs, strict=True):
                inner = member_spec(spec)
                if inner is None:
                    joint_specs[name] = spec
                    continue
                if not inner:
                    raise FilterError(f"{spec}: expected independent:FILTER, e.g. independent:ukf")
                for i, r in enumerate(team.robots):
                    if name in broken:
                        member_built[i][name] = None
                        continue
                    try:
                        member_built[i][name] = build_filter(
                            inner, r.scenario, seed, name=f"{name}/{r.id}", params=settings.get(name),
                            limit_s=build_limit_s, secret=secret)
                    except FilterError:
                        raise
                    except Exception as exc:  # a student's __init__ or reset
                        member_built[i][name] = None
                        broken[name] = (f"construction failed on robot {r.name}: {one_line(exc)}",
                                        traceback.format_exc())
                for i in range(len(team.robots)):  # one copy broken: none of them runs
                    if name in broken:
                        member_built[i][name] = None
        self.member_names = [n for n in self.names if n not in joint_specs]
        self.members = [FilterRunner({n: b.get(n) for n in self.member_names if n in b},
                                     step_limit_s=step_limit_s, run_limit_s=run_limit_s, keep=keep,
                                     cpu_limits=cpu_limits) for b in member_built]
        for name, (why, tb) in broken.items():
            for runner in self.members:
                if name in runner.tracks:
                    runner.tracks[name].failed, runner.tracks[name].traceback = why, tb
        joint_built, joint_why = build_team_filters(
            list(joint_specs),
            lambda n: build_team_spec(joint_specs[n], team, settings.get(n), seed), build_limit_s)
        self.joint = JointRunner(joint_built, self.n_robots, step_limit_s=step_limit_s, keep=keep,
                                 cpu_limits=cpu_limits)
        for name, reason in joint_why.items():
            self.joint.tracks[name].failed = f"could not be built: {reason}"

    @classmethod
    def around(cls, team: TeamScenario, members: Sequence[FilterRunner],
               joint: JointRunner | None = None) -> TeamRunner:
        """A TeamRunner over runners already built and fed elsewhere (a replay's): ``members[i]``
        robot i's FilterRunner of the single-robot filters (one per robot), ``joint`` the
        team filters' JointRunner (None: none)."""
        if len(members) != team.n_robots:
            raise ValueError(f"{len(members)} member runners for a team of {team.n_robots}")
        runner = cls.__new__(cls)
        runner.team, runner.n_robots, runner.members = team, team.n_robots, list(members)
        runner.joint = joint if joint is not None else JointRunner({}, team.n_robots)
        runner.member_names = list(members[0].tracks)
        runner.names = runner.member_names + [n for n in runner.joint.tracks if n not in members[0].tracks]
        return runner

    def is_member(self, name: str) -> bool:
        """Whether ``name`` is a single-robot filter run on each robot (else a team filter)."""
        return name in self.members[0].tracks

    def track(self, name: str, robot: int = 0) -> FilterTrack:
        """Robot ``robot``'s track of single-robot filter ``name`` (means (3,) per tick), or
        the team filter's joint track (means (N, 3) per tick)."""
        if self.is_member(name):
            return self.members[robot].tracks[name]
        return self.joint.tracks[name]

    def failed(self, name: str) -> str | None:
        """Why filter ``name`` was switched off (on any robot), or None."""
        if not self.is_member(name):
            return self.joint.tracks[name].failed
        for runner in self.members:
            why = runner.tracks[name].failed
            if why:
                return why
        return None

    def fail(self, name: str, reason: str, tb: str = "", time_s: float | None = None) -> None:
        """Switch ``name`` off on every robot with ``reason`` (one line) at ``time_s`` [s]."""
        if self.is_member(name):
            for runner in self.members:
                runner.fail(name, reason, tb, time_s)
        else:
            self.joint.fail(name, reason, tb, time_s)

    def feed(self, step: TeamStep) -> None:
        """One team tick: each robot's single-robot filters get that robot's Step (beacon
        readings), the team filters every robot's command and readings."""
        for runner, s in zip(self.members, step.steps, strict=True):
            runner.feed(s)
        if self.n_robots > 1 and self.member_names:
            self._spread_failures(step.time)
        if self.joint.tracks:
            self.joint.feed(step.tick, step.time, [s.control for s in step.steps], step.dt,
                            [step.measurements(i) for i in range(len(step.steps))])

    def _spread_failures(self, time_s: float) -> None:
        """A copy that failed on robot i switches the filter off on the others too."""
        for name in self.member_names:
            bad = [(r, self.members[k].tracks[name]) for k, r in enumerate(self.team.robots)
                   if self.members[k].tracks[name].failed]
            if not bad or len(bad) == self.n_robots:
                continue
            robot, tr = bad[0]
            for runner in self.members:
                runner.fail(name, f"robot {robot.name}: {tr.failed}", tr.traceback,
                            tr.failed_time_s if tr.failed_time_s is not None else time_s)

    def latest(self, name: str) -> tuple[np.ndarray, np.ndarray] | None:
        """Every robot's latest estimate under ``name``: (means (N, 3), covs (N, 3, 3)), or
        None before the first estimate."""
        if not self.is_member(name):
            tr = self.joint.tracks[name]
            return (tr.means[-1], tr.covs[-1]) if tr.means else None
        tracks = [r.tracks[name] for r in self.members]
        if any(not t.means for t in tracks):
            return None
        return (np.array([t.means[-1] for t in tracks]), np.array([t.covs[-1] for t in tracks]))

    def series(self, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The ticks every robot has an estimate of (T,), and the estimates: means (T, N, 3)
        [m, m, rad], covs (T, N, 3, 3)."""
        if not self.is_member(name):
            tr = self.joint.tracks[name]
            n = self.n_robots
            return (np.array(tr.ticks, dtype=np.int64), np.array(tr.means).reshape(-1, n, 3),
                    np.array(tr.covs).reshape(-1, n, 3, 3))
        tracks = [r.tracks[name] for r in self.members]
        t = min(len(tr.ticks) for tr in tracks)
        ticks = np.array(list(tracks[0].ticks)[:t], dtype=np.int64)
        means = np.stack([np.array(list(tr.means)[:t]).reshape(-1, 3) for tr in tracks], axis=1)
        covs = np.stack([np.array(list(tr.covs)[:t]).reshape(-1, 3, 3) for tr in tracks], axis=1)
        return ticks, means, covs

    def team_tracks(self) -> dict[str, Any]:
        """Every filter as one track over the team (what a team recording digests): a team
        filter's joint track; for a single-robot filter a :class:`StackedTrack` of its copies
        (the same object each call)."""
        views = self.__dict__.setdefault("_views", {})
        out: dict[str, Any] = {}
        for name in self.names:
            if self.is_member(name):
                if name not in views:
                    views[name] = StackedTrack(name, [r.tracks[name] for r in self.members])
                out[name] = views[name]
            else:
                out[name] = self.joint.tracks[name]
        return out


class _Copies:
    """The copies of a single-robot filter on a team, seen as one filter: ``params`` (none
    of its own) and ``filters`` (robot i's copy), as a team filter of independent copies."""

    def __init__(self, tracks: list[FilterTrack]):
        self._tracks = tracks
        self.params: dict[str, Any] = {}

    @property
    def filters(self) -> list[Any]:
        return [t.filter for t in self._tracks]


class StackedTrack:
    """A single-robot filter's copies on a team as one track whose latest estimate is every
    robot's (``means[-1]`` (N, 3), ``covs[-1]`` (N, 3, 3)), at the tick all copies reached."""

    def __init__(self, name: str, tracks: list[FilterTrack]):
        self.name = name
        self._tracks = tracks
        self.filter = _Copies(tracks)

    @property
    def failed(self) -> str | None:
        return next((t.failed for t in self._tracks if t.failed), None)

    @property
    def ticks(self) -> list[int]:
        last = [t.ticks[-1] if t.ticks else None for t in self._tracks]
        return [last[0]] if last[0] is not None and all(k == last[0] for k in last) else []

    @property
    def means(self) -> list[np.ndarray]:
        return [np.array([t.means[-1] for t in self._tracks])] if self.ticks else []

    @property
    def covs(self) -> list[np.ndarray]:
        return [np.array([t.covs[-1] for t in self._tracks])] if self.ticks else []
