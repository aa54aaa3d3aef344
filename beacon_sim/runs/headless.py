"""One headless run over N robots: a scenario, a seed, some filters; the figures ``run`` prints.

A single robot is a team of one: :func:`run_headless` takes a single-robot
:class:`~beacon_sim.core.scenario.Scenario` as :func:`~beacon_sim.core.scenario.as_team`
makes it, and runs every scenario the same way, a
:class:`~beacon_sim.core.team.TeamSimulation` fed tick by tick to a
:class:`~beacon_sim.hosting.team_runner.TeamRunner`. A team of one draws from the run's own
seed, so its truth and its filters' estimates are the single-robot run's bit for bit.

The simulation and the filters see exactly the same ticks; the truth does not depend on the
filters. A filter that cannot be built, raises, hangs or returns an unusable estimate is
switched off with a message, the others go on, and it gets no score.

:class:`RunResult` holds the run over N robots; as HighwayEnv's ``vehicle =
controlled_vehicles[0]``, its single-robot views (``scenario``, ``steps``, ``runner``,
``truth``) are robot 0's, which for a single robot is *the* robot.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from beacon_sim.core.metrics import anees_band, nees, pose_errors, summary
from beacon_sim.core.scenario import Scenario, TeamScenario, as_team, team_of_one
from beacon_sim.core.team import TeamSimulation, TeamStep
from beacon_sim.core.types import Step
from beacon_sim.hosting.guard import NEES_NOT_FINITE
from beacon_sim.hosting.runner import HEADLESS_STEP_LIMIT_S, FilterRunner, FilterTrack, failure_text
from beacon_sim.hosting.team_runner import TeamRunner
from beacon_sim.runs.progress import Progress

#: The figures of a run that a failed filter does not get (null in JSON, empty in CSV).
ACCURACY_KEYS = ("pos_rmse_m", "heading_rmse_rad", "mse_x", "mse_y", "mse_theta", "anees")

#: A run that costs more than this [s of CPU per simulated second] says so, once, naming
#: what costs it (``run``, ``eval``): a world or a filter that slow would otherwise look hung.
SLOW_CPU_PER_SIM_S = 3.0
#: It is judged once this much CPU has been spent [s], so the start-up costs do not count.
SLOW_JUDGED_AFTER_CPU_S = 1.0


def slow_note(who: str, per_sim_s: float, simulated_s: float, what: str = "CPU") -> str:
    """The one line saying a run is slow: ``who`` (a filter, or "the simulation") costs
    ``per_sim_s`` seconds of ``what`` per simulated second, so ``simulated_s`` simulated
    seconds take about that many times longer."""
    total = per_sim_s * simulated_s
    took = f"{total / 60:.0f} min" if total >= 120 else f"{total:.0f} s"
    return (f"note: {who} costs {per_sim_s:.1f} s of {what} per simulated second (over "
            f"{SLOW_CPU_PER_SIM_S:g}); {simulated_s:g} s simulated will take about {took}")


def anees_verdict(value: float, lo: float, hi: float) -> str:
    """``consistent`` inside the band [lo, hi], ``optimistic`` above it (errors larger than
    the covariance admits), ``pessimistic`` below, ``failed`` when not finite."""
    if not np.isfinite(value):
        return "failed"
    return "optimistic" if value > hi else "pessimistic" if value < lo else "consistent"


def team_step_of(step: Step) -> TeamStep:
    """A single robot's :class:`Step` as the tick of a team of one (no robot readings)."""
    return TeamStep(step.tick, step.time, step.dt, (step,), ((),))


@dataclass
class RunResult:
    """What a headless run over N robots produced: the ticks, every filter's tracks, counters.

    ``team_steps[k]`` is tick k + 1 of every robot; ``filters`` runs every filter (robot i's
    single-robot filters in ``filters.members[i]``, team filters in ``filters.joint``).
    ``wall_s`` [s]: the whole loop; ``sim_wall_s`` [s]: the simulation's share of it.
    """

    team: TeamScenario
    seed: int
    team_steps: list[TeamStep]
    filters: TeamRunner
    wall_s: float
    sim_wall_s: float
    truth_checksum: str
    extra: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def of_single(cls, scenario: Scenario, seed: int, steps: list[Step], runner: FilterRunner,
                  wall_s: float, sim_wall_s: float, truth_checksum: str) -> RunResult:
        """The result of a single-robot run fed elsewhere (a replay) as a run of a team of one."""
        team = team_of_one(scenario)
        return cls(team, seed, [team_step_of(s) for s in steps], TeamRunner.around(team, [runner]),
                   wall_s, sim_wall_s, truth_checksum)

    # -- the N robots ------------------------------------------------------------------
    @property
    def n_robots(self) -> int:
        return self.team.n_robots

    @property
    def names(self) -> list[str]:
        """The filters' names, in the order given."""
        return list(self.filters.names)

    def robot_steps(self, i: int = 0) -> list[Step]:
        """Robot i's :class:`Step` of every tick."""
        return [s.steps[i] for s in self.team_steps]

    @property
    def true_poses(self) -> np.ndarray:
        """True poses after each tick, shape (T, N, 3) [m, m, rad]."""
        return np.array([s.true_poses for s in self.team_steps]).reshape(-1, self.n_robots, 3)

    @property
    def initial_poses(self) -> np.ndarray:
        """True poses before the first tick, shape (N, 3) (each robot's ``initial_pose``)."""
        return np.array([r.scenario.initial_pose for r in self.team.robots], dtype=float)

    @property
    def controls(self) -> np.ndarray:
        """Each robot's command of each tick, shape (T, N, 2) [m/s, rad/s]."""
        return np.array([[(st.control.v, st.control.omega) for st in s.steps] for s in self.team_steps],
                        dtype=float).reshape(len(self.team_steps), self.n_robots, 2)

    def track(self, name: str) -> FilterTrack:
        """Filter ``name``'s track: a team filter's joint one, a single-robot filter's on the
        first robot it failed on (else robot 0's)."""
        if not self.filters.is_member(name):
            return self.filters.joint.tracks[name]
        tracks = [m.tracks[name] for m in self.filters.members]
        return next((t for t in tracks if t.failed), tracks[0])

    @property
    def tracks(self) -> dict[str, FilterTrack]:
        """Every filter's :meth:`track`, by name."""
        return {name: self.track(name) for name in self.names}

    def failed(self, name: str) -> str | None:
        """Why filter ``name`` was switched off (with the time), or None."""
        return failure_text(self.track(name))

    def us_per_step(self, name: str) -> float:
        """Filter ``name``'s mean time per tick [microseconds], over every robot's copy."""
        if not self.filters.is_member(name):
            return self.filters.joint.tracks[name].us_per_step
        return sum(m.tracks[name].us_per_step for m in self.filters.members)

    def _estimates(self, name: str, i: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Robot i's estimates under ``name`` and the truth at their ticks: means (T', 3),
        covs (T', 3, 3), truths (T', 3)."""
        ticks, means, covs = self.filters.series(name)
        row = {s.tick: k for k, s in enumerate(self.team_steps)}
        truths = self.true_poses[[row[int(t)] for t in ticks], i]
        return (np.ascontiguousarray(means[:, i]), np.ascontiguousarray(covs[:, i]),
                np.ascontiguousarray(truths.reshape(-1, 3)))

    def robot_summary(self, name: str, i: int) -> dict[str, float]:
        """Robot i's figures under filter ``name`` (core.metrics.summary: RMSE, ANEES)."""
        return summary(*self._estimates(name, i))

    def nees(self, name: str, i: int) -> np.ndarray:
        """Robot i's NEES per tick (3 dof) under filter ``name``."""
        means, covs, truths = self._estimates(name, i)
        return nees(pose_errors(means, truths), covs)

    def fail_unbounded_nees(self) -> None:
        """Switch off, after the run, every filter whose NEES against the truth is not finite
        at some tick (a covariance that leaves no room for the error it had), from that tick,
        with the one line ``eval``, ``check`` and ``grade`` give
        (:data:`~beacon_sim.hosting.guard.NEES_NOT_FINITE`): such a filter is never scored as
        working. A failure it had later is replaced by this earlier one."""
        row = {s.tick: k for k, s in enumerate(self.team_steps)}
        for name in self.names:
            ticks, means, covs = self.filters.series(name)
            if not len(ticks):
                continue
            truths = self.true_poses[[row[int(t)] for t in ticks]]
            with np.errstate(all="ignore"):
                values = [nees(pose_errors(means[:, i], truths[:, i]), covs[:, i])
                          for i in range(self.n_robots)]
            bad = [int(np.argmax(~np.isfinite(v))) for v in values if not np.isfinite(v).all()]
            if not bad:
                continue
            k = min(bad)
            tracks = ([m.tracks[name] for m in self.filters.members] if self.filters.is_member(name)
                      else [self.filters.joint.tracks[name]])
            for tr in tracks:
                tr.failed, tr.traceback = NEES_NOT_FINITE, ""
                tr.failed_time_s = self.team_steps[row[int(ticks[k])]].time

    def readings(self) -> list[dict[str, int]]:
        """Per robot: beacon readings and robot readings over the run."""
        return [{"beacon": sum(len(m) for s in self.team_steps for m in s.steps[i].measurements),
                 "robot": sum(len(m) for s in self.team_steps for m in s.robot_readings[i])}
                for i in range(self.n_robots)]

    # -- robot 0: the single robot -----------------------------------------------------
    @property
    def scenario(self) -> Scenario:
        """Robot 0's scenario (a single-robot run's scenario)."""
        return self.team.robots[0].scenario

    @cached_property
    def steps(self) -> list[Step]:
        """Robot 0's steps (a single-robot run's steps)."""
        return self.robot_steps(0)

    @property
    def runner(self) -> FilterRunner:
        """Robot 0's FilterRunner of the single-robot filters (a single-robot run's runner)."""
        return self.filters.members[0]

    @property
    def truth(self) -> np.ndarray:
        """Robot 0's true poses after each step, shape (T, 3)."""
        return self.true_poses[:, 0]

    def distance(self, i: int = 0) -> float:
        """Length of robot i's true path [m], kidnap jumps excluded."""
        d = 0.0
        prev = np.array(self.team.robots[i].scenario.initial_pose)
        for s in self.robot_steps(i):
            if not s.kidnapped:
                d += float(np.hypot(*(s.true_pose[:2] - prev[:2])))
            prev = s.true_pose
        return d

    def measurement_counts(self, i: int = 0) -> dict[str, int]:
        """Robot i's readings per sensor (beacon sightings for beacon sensors, fixes for fix
        sensors)."""
        counts = {s.name: 0 for s in self.team.robots[i].scenario.sensors}
        for s in self.robot_steps(i):
            for m in s.measurements:
                counts[m.sensor] += len(m)
        return counts

    # -- the figures -------------------------------------------------------------------
    def filter_summary(self) -> dict[str, dict[str, Any]]:
        """Per filter, a single robot's figures (``run --json``'s ``filters``)."""
        out: dict[str, dict[str, Any]] = {}
        for name in self.names:
            tr = self.track(name)
            row: dict[str, Any] = {}
            if tr.failed:  # no score for a filter that failed: its figures would flatter it
                row.update(dict.fromkeys(ACCURACY_KEYS))
            elif tr.means:
                row.update(self.robot_summary(name, 0))
            row["us_per_step"] = self.us_per_step(name)
            if tr.failed:
                row["failed"] = tr.failed
                row["failed_time_s"] = tr.failed_time_s
            if tr.slow_warning:
                row["slow_warning"] = tr.slow_warning
            out[name] = row
        return out

    def team_filter_summary(self) -> dict[str, dict[str, Any]]:
        """Per filter, each robot's figures (core.metrics.summary) with its ANEES verdict
        against the 95 % band of one run's NEES (``anees_band(1)``, 3 dof: consecutive steps
        are correlated, so the band is not narrowed by their number, as in ``eval``), and the
        team's: RMSE over all robots, mean ANEES against the band of N robots' NEES. A failed
        filter has only ``failed`` (the reason and the time): no score."""
        band, team_band = anees_band(1), anees_band(self.n_robots)
        out: dict[str, dict[str, Any]] = {}
        for name in self.names:
            if self.failed(name):
                out[name] = {"failed": self.failed(name)}
                continue
            if not len(self.filters.series(name)[0]):
                out[name] = {"robots": {}, "no_steps": True, "us_per_step": self.us_per_step(name)}
                continue
            robots: dict[str, dict[str, Any]] = {}
            for i, r in enumerate(self.team.robots):
                fig = self.robot_summary(name, i)
                robots[r.name] = {**fig, "anees_verdict": anees_verdict(fig["anees"], *band)}
            team_anees = float(np.mean([v["anees"] for v in robots.values()]))
            out[name] = {
                "robots": robots,
                "team_pos_rmse_m": float(np.sqrt(np.mean([v["pos_rmse_m"] ** 2 for v in robots.values()]))),
                "team_heading_rmse_rad": float(np.sqrt(np.mean([v["heading_rmse_rad"] ** 2
                                                                for v in robots.values()]))),
                "team_anees": team_anees,
                "team_anees_verdict": anees_verdict(team_anees, *team_band),
                "us_per_step": self.us_per_step(name),
            }
        return out

    def as_json(self) -> dict[str, Any]:
        """What ``run --json`` prints: for a single robot, its path, readings and each
        filter's figures; for a team (a ``[[robots]]`` file), each robot's and the team's."""
        steps = len(self.team_steps)
        if self.team.solo:
            return {
                "scenario": self.team.name,
                "seed": self.seed,
                "steps": steps,
                "sim_time_s": round(steps * self.team.dt, 9),
                "distance_m": self.distance(),
                "measurements": self.measurement_counts(),
                "events": [{"kind": e.kind, "tick": e.tick, "time": e.time, "detail": e.detail}
                           for s in self.steps for e in s.events],
                "truth_checksum": self.truth_checksum,
                "steps_per_s": steps / self.sim_wall_s if self.sim_wall_s else None,
                "filters": self.filter_summary(),
            }
        names = [r.name for r in self.team.robots]
        return {"scenario": self.team.name, "team": True, "seed": self.seed, "steps": steps,
                "sim_time_s": steps * self.team.dt, "robots": names,
                "anees_band": list(anees_band(1)), "team_anees_band": list(anees_band(self.n_robots)),
                "readings": dict(zip(names, self.readings(), strict=True)),
                "truth_checksum": self.truth_checksum, "filters": self.team_filter_summary()}


def run_headless(scenario: Scenario | TeamScenario, filters: list[str] | None = None,
                 seed: int | None = None, duration: float | None = None,
                 params: dict[str, dict[str, Any]] | None = None, progress: bool = False, *,
                 step_limit_s: float | None = HEADLESS_STEP_LIMIT_S,
                 run_limit_s: float | None = None, secret: bytes | None = None,
                 on_tick: Callable[[Any, TeamRunner], None] | None = None,
                 on_slow: Callable[[str], None] | None = None) -> RunResult:
    """Simulate ``duration`` seconds (default: the scenario's) and feed every filter.

    ``filters``: for a single robot, filter specs (built-in names, ``pkg.mod:Class``,
    ``file.py:Class``); for a team, team filter specs (``hosting/team_specs.py``:
    ``centralised``, ``independent:F``, ``file.py:MyTeam``); None runs the scenario's
    ``default_filters``. ``params``: ``{filter name: {key: value}}``. ``step_limit_s`` [s]: a
    tick of a filter that takes longer stops it; ``run_limit_s`` [s]: so does its filter time
    in the run passing this (``eval --time-limit``). ``progress``: a progress bar on stderr
    once the run has taken a second. ``secret``: the key of the filters' random streams
    (None: the public key, reproducible from the seed alone; ``grade``'s secret).
    ``on_tick(step, runner)`` is called after the filters took each tick (an export reads
    their beliefs there). ``on_slow(line)`` is called once, as soon as the run has cost more
    than ``SLOW_CPU_PER_SIM_S`` seconds of CPU (this thread's: the simulation and the filters
    run in it) per simulated second, with a line naming the simulation or the filter that
    costs most (:func:`slow_note`).
    """
    team = as_team(scenario)
    seed = team.seed if seed is None else seed
    duration = team.duration if duration is None else duration
    specs = list(team.default_filters if filters is None else filters)
    runner = TeamRunner(team, specs, seed, params, step_limit_s=step_limit_s, run_limit_s=run_limit_s,
                        secret=secret)
    joint = runner.joint.tracks
    sim = TeamSimulation(team, seed)
    n = round(duration / team.dt)
    bar = Progress(n, f"run {team.name}", progress, unit="ticks")
    steps = []
    t0 = time.perf_counter()
    sim_ns = 0
    cpu0 = time.thread_time_ns()
    sim_cpu_ns = 0
    for _ in range(n):
        a = time.perf_counter_ns()
        ca = time.thread_time_ns()
        step = sim.step()
        sim_cpu_ns += time.thread_time_ns() - ca
        sim_ns += time.perf_counter_ns() - a
        steps.append(step)
        runner.feed(step)
        if on_slow is not None:
            cpu = (time.thread_time_ns() - cpu0) / 1e9
            if cpu > SLOW_JUDGED_AFTER_CPU_S and cpu > SLOW_CPU_PER_SIM_S * step.time:
                on_slow(slow_note(_costliest(runner, sim_cpu_ns / 1e9, cpu), cpu / step.time, duration))
                on_slow = None
        if on_tick is not None:
            on_tick(step, runner)
        if run_limit_s is not None:  # the team filters' run limit (the members' is their runner's)
            for name, tr in joint.items():
                if not tr.failed and tr.step_ns > run_limit_s * 1e9:
                    runner.fail(name, f"time limit: over {run_limit_s:g} s of filter time in the run",
                                "", step.time)
        bar.advance()
    wall = time.perf_counter() - t0
    checksum = sim.truth_checksum  # a team of one: its robot's own (TeamSimulation)
    result = RunResult(team, seed, steps, runner, wall, sim_ns / 1e9, checksum)
    result.fail_unbounded_nees()
    return result


def _costliest(runner: TeamRunner, sim_cpu_s: float, cpu_s: float) -> str:
    """What costs a slow run most: "the simulation" when it took over half of ``cpu_s``,
    else the filter with the most step time (over every robot's copy), named."""
    if sim_cpu_s > 0.5 * cpu_s:
        return "the simulation"
    cost: dict[str, int] = {}
    for r in runner.members:
        for name, tr in r.tracks.items():
            cost[name] = cost.get(name, 0) + tr.step_ns
    for name, tr in runner.joint.tracks.items():
        cost[name] = cost.get(name, 0) + tr.step_ns
    return f"filter {max(cost, key=lambda k: cost[k])}" if cost else "the run"
