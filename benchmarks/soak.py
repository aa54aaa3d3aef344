"""Soaks: long runs that check after every step that each filter's estimate is finite with a
symmetric positive semi-definite covariance (the runner's own guard, ``validate_estimate``)
and that its NEES against the truth is finite. Two kinds:

``filters`` (the default): every built-in filter on one scenario for a long run with random
driving, frequent kidnaps and resets. A filter that is switched off is counted, then built
again from the initial belief so the soak goes on. The particle filter runs with 300
particles and the grid with 0.5 m cells so that 10^6 steps take an hour or so, not a day.

    python benchmarks/soak.py filters --steps 1000000 --scenario default --seed 424242

``scenarios``: every shipped scenario (the team ones too) as it is, with its
``default_filters`` and its own settings, for ``--steps`` ticks each; nothing is rebuilt: a
filter switched off stays off and is reported.

    python benchmarks/soak.py scenarios --steps 200000 --seed 424242 [--only office ...]

Step limits count CPU time (``cpu_limits``), so a busy machine switches nothing off. Printed
per filter: switched-off count (with the tick and reason of the first), largest variance
seen (largest diagonal entry of any covariance [m^2 or rad^2]), largest and final NEES
(3 dof), microseconds per step; per soak: steps, simulated time, CPU and wall time. Exit
status 1 when anything was switched off or not finite.
"""

from __future__ import annotations

import argparse
import math
import time
from collections import Counter
from dataclasses import dataclass, field, replace

import numpy as np

from beacon_sim.core.drivers import RandomGoalSpec
from beacon_sim.core.metrics import nees, pose_errors
from beacon_sim.core.resources import shipped_scenarios
from beacon_sim.core.scenario import load_any_scenario, load_scenario, shipped_team_scenarios
from beacon_sim.core.simulation import Simulation
from beacon_sim.core.team import TeamSimulation
from beacon_sim.hosting.loading import BUILTIN_FILTERS, build_filter, reset_filter
from beacon_sim.hosting.runner import HEADLESS_STEP_LIMIT_S, FilterRunner, validate_estimate
from beacon_sim.hosting.team_runner import TeamRunner

PARAMS = {"pf": {"n_particles": 300}, "histogram": {"cell": 0.5}}
KIDNAP_EVERY = 700      # ticks between kidnaps (random pose), on average
RESET_EVERY = 400       # ticks between resets of every filter (R), on average
GLOBAL_EVERY = 2500     # ticks between global resets (G), on average


@dataclass
class Tally:
    """One filter's figures over a soak."""

    off: int = 0
    first: str = ""
    max_var: float = 0.0
    max_nees: float = 0.0
    final_nees: float = math.nan
    us_per_step: float = math.nan
    reasons: Counter[str] = field(default_factory=Counter)

    def see(self, means: np.ndarray, covs: np.ndarray, truths: np.ndarray) -> str | None:
        """Take one step's estimates (means (N, 3), covs (N, 3, 3)) against the truths
        (N, 3); why they are unusable, or None."""
        for m, c in zip(means, covs, strict=True):
            checked = validate_estimate((np.array(m, dtype=float), np.array(c, dtype=float)))
            if isinstance(checked, str):
                return checked
        self.max_var = max(self.max_var, float(np.max(np.diagonal(covs, axis1=-2, axis2=-1))))
        with np.errstate(all="ignore"):
            v = nees(pose_errors(means, truths), covs)
        if not np.isfinite(v).all():
            return "NEES not finite"
        self.final_nees = float(np.mean(v))
        self.max_nees = max(self.max_nees, float(np.max(v)))
        return None

    def count(self, tick: int, why: str) -> None:
        self.off += 1
        self.reasons[why] += 1
        self.first = self.first or f"tick {tick}: {why}"


def report(title: str, steps: int, dt: float, cpu: float, wall: float, tallies: dict[str, Tally]) -> int:
    """Print one soak's figures; the number of filters switched off at least once."""
    print(f"soak {title}: {steps:,} steps ({steps * dt / 3600:.1f} h simulated), CPU {cpu:.0f} s, "
          f"wall {wall:.0f} s", flush=True)
    for name, t in tallies.items():
        print(f"  {name:<16} switched off {t.off:>3}  max var {t.max_var:10.3g}  max NEES "
              f"{t.max_nees:10.3g}  final NEES {t.final_nees:8.3g}  {t.us_per_step:8.1f} us/step"
              + (f"  first: {t.first}" if t.first else ""), flush=True)
    return sum(1 for t in tallies.values() if t.off)


def soak_filters(steps: int, scenario_name: str, seed: int) -> int:
    """Every built-in filter on ``scenario_name`` with random driving, kidnaps and resets."""
    sc = load_scenario(scenario_name)
    sc = replace(sc, driver=RandomGoalSpec(speed=0.4))  # random driving, whatever the file says
    rng = np.random.default_rng(seed)
    names = list(BUILTIN_FILTERS)
    filters = {n: build_filter(n, sc, seed, params=PARAMS.get(n)) for n in names}
    runner = FilterRunner(filters, step_limit_s=HEADLESS_STEP_LIMIT_S, keep=1, cpu_limits=True)
    sim = Simulation(sc, seed)
    tallies = {n: Tally() for n in names}
    kidnaps = resets = 0
    c0, t0 = time.process_time(), time.perf_counter()
    for k in range(1, steps + 1):
        if rng.random() < 1 / KIDNAP_EVERY:
            sim.request_kidnap(None)
            kidnaps += 1
        if rng.random() < 1 / RESET_EVERY:
            for f in filters.values():
                reset_filter(f, sc)
            resets += 1
        if rng.random() < 1 / GLOBAL_EVERY:
            for f in filters.values():
                if getattr(f, "supports_global", False):
                    f.reset(None)
            resets += 1
        step = sim.step()
        runner.feed(step)
        truth = np.asarray(step.true_pose, dtype=float)[None]
        for name, tr in runner.tracks.items():
            why = tr.failed or tallies[name].see(np.asarray(tr.means[-1])[None],
                                                 np.asarray(tr.covs[-1])[None], truth)
            if why is not None:  # count it, then start the filter again from the initial belief
                tallies[name].count(k, why)
                f = build_filter(name, sc, seed + k, params=PARAMS.get(name))
                filters[name] = f
                runner.tracks[name] = FilterRunner({name: f}, step_limit_s=HEADLESS_STEP_LIMIT_S,
                                                   keep=1, cpu_limits=True).tracks[name]
        if k % max(1, steps // 10) == 0 or k == steps:  # the figures so far, in case it is cut short
            for name, tr in runner.tracks.items():
                tallies[name].us_per_step = tr.us_per_step
            title = (f"{sc.name}, every built-in filter, seed {seed} ({kidnaps} kidnaps, {resets} "
                     f"resets; pf {PARAMS['pf']}, histogram {PARAMS['histogram']})"
                     + ("" if k == steps else f" [so far, of {steps:,}]"))
            off = report(title, k, sc.dt, time.process_time() - c0, time.perf_counter() - t0, tallies)
    return off


def soak_scenario(name: str, steps: int, seed: int) -> int:
    """Shipped scenario ``name`` as it is, with its default filters, for ``steps`` ticks."""
    team = load_any_scenario(name)
    runner = TeamRunner(team, list(team.default_filters), seed, step_limit_s=HEADLESS_STEP_LIMIT_S,
                        keep=1, cpu_limits=True)
    sim = TeamSimulation(team, seed)
    tallies = {n: Tally() for n in runner.names}
    live = set(runner.names)
    c0, t0 = time.process_time(), time.perf_counter()
    for k in range(1, steps + 1):
        step = sim.step()
        runner.feed(step)
        truths = np.asarray(step.true_poses, dtype=float).reshape(-1, 3)
        for n in list(live):
            why = runner.failed(n)
            if why is None:
                est = runner.latest(n)
                if est is not None:
                    why = tallies[n].see(est[0].reshape(-1, 3), est[1].reshape(-1, 3, 3), truths)
            if why is not None:  # switched off for good: counted once
                tallies[n].count(k, why)
                live.discard(n)
        if k % max(1, steps // 10) == 0 or k == steps:  # the figures so far, in case it is cut short
            for n in runner.names:
                tallies[n].us_per_step = sum(runner.track(n, i).us_per_step for i in range(team.n_robots)
                                             if runner.is_member(n) or i == 0)
            off = report(f"{team.name} (default filters, seed {seed})"
                         + ("" if k == steps else f" [so far, of {steps:,}]"), k, team.dt,
                         time.process_time() - c0, time.perf_counter() - t0, tallies)
    return off


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("kind", nargs="?", choices=["filters", "scenarios"], default="filters")
    p.add_argument("--steps", type=int, default=None,
                   help="steps (default 10^6 for filters, 200,000 per scenario)")
    p.add_argument("--scenario", default="default", help="the filters soak's scenario")
    p.add_argument("--only", nargs="*", default=None, help="the scenarios soak: these scenarios only")
    p.add_argument("--seed", type=int, default=424242, help="a seed no test, doc or check uses")
    a = p.parse_args()
    if a.kind == "filters":
        return 1 if soak_filters(a.steps or 1_000_000, a.scenario, a.seed) else 0
    names = a.only or [*shipped_scenarios(), *shipped_team_scenarios()]
    bad = sum(soak_scenario(n, a.steps or 200_000, a.seed) for n in names)
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
