"""``beacon-sim check FILTER [--scenario S] [--sandbox LEVEL]``: the conformance report for a
filter. A filter file, a module filter (``pkg.mod:Class``) or an entry-point filter runs in a
process of its own (docs/grading.md): its code never runs in
``check``'s process, so a file that exits, loops or raises ``KeyboardInterrupt`` fails a
check instead of ending the program. A SLAM filter (one with ``landmarks()``) is also
asked for a well-formed map after every step (the ``landmarks`` line, docs/slam.md); a
hosted file's map comes back over the pipe with each estimate and is judged here.

A team filter (a class with ``estimates()``, docs/multi-robot.md "Your own team filter") is
checked on a team scenario by :func:`run_team_checks`: it loads, has the four methods,
builds with a TeamContext, runs under the guard of the one headless run with a usable
estimate of every robot on every tick, and gives the same bits twice for the same seed."""

from __future__ import annotations

import argparse
import ast
from functools import partial
from pathlib import Path

import numpy as np

from beacon_sim.core.files import MAX_SOURCE_BYTES, check_user_file
from beacon_sim.core.scenario import TeamScenario, is_team_scenario, load_scenario, load_team_scenario
from beacon_sim.hosting.conformance import CheckResult, print_report, run_checks
from beacon_sim.hosting.containment import SandboxError
from beacon_sim.hosting.loading import FilterLoadError, load_filter_class
from beacon_sim.hosting.sources import hosted_source
from beacon_sim.runs.headless import run_headless

#: The methods a team filter implements (filters/team.TeamFilter).
TEAM_METHODS = ("reset", "predict", "update", "estimates")
#: Simulated time each run of the team check lasts [s].
CHECK_DURATION_S = 10.0


def _is_team_file(path: Path, class_name: str | None) -> bool:
    """Whether the file's filter is a team filter (a class with ``estimates()`` and no
    ``estimate()``), read without running it."""
    try:
        tree = ast.parse(path.read_text(encoding="utf-8"))
    except (SyntaxError, UnicodeDecodeError, OSError, ValueError):
        return False
    classes = {n.name: n for n in tree.body if isinstance(n, ast.ClassDef)}

    def methods(name: str, seen: frozenset[str] = frozenset()) -> set[str]:
        node = classes.get(name)
        if node is None or name in seen:
            return set()
        own = {f.name for f in node.body if isinstance(f, ast.FunctionDef)}
        for base in node.bases:  # the bases defined in the same file
            if isinstance(base, ast.Name):
                own |= methods(base.id, seen | {name})
        return own

    for name in classes:
        if class_name is None or name == class_name:
            m = methods(name)
            if "estimates" in m and "estimate" not in m:
                return True
    return False


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
    run = partial(run_headless, team, [spec], seed=0, duration=CHECK_DURATION_S)
    first = run()
    name = first.names[0]
    why = first.failed(name)
    if why:
        results.append(CheckResult("runs", False, why,
                                   "fix the error above (beacon-sim run "
                                   f"{team.name} --filter {spec} shows the traceback's last line)"))
        return results
    results.append(CheckResult("runs", True, f"{len(first.team_steps)} ticks of {team.name}, "
                               f"{team.n_robots} robots, a usable estimate of every robot on every tick"))
    a, b = first.filters.series(name), run().filters.series(name)
    same = all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    results.append(CheckResult(
        "deterministic", same, "same seed, same bits" if same else "two runs with seed 0 differ",
        "draw random numbers only from ctx.members[i].ctx.rng (seeded), never np.random or time"))
    return results


def check_command(args: argparse.Namespace) -> int:
    """The report; exit status 0 when every check passes, 1 when one fails, 2 (one line)
    when the name is not a filter at all (unknown name, missing file or class). A team
    filter class (one with ``estimates()``) is checked on a team scenario (default
    ``team_sparse``), in this process."""
    sandbox = getattr(args, "sandbox", None) or "auto"
    where = hosted_source(args.filter) if sandbox != "none" else None  # a file or a module
    if where is not None:
        source, cls_name = where
        path = source if isinstance(source, Path) else source.origin()
        if isinstance(source, Path) and not source.exists():
            raise FilterLoadError(f"{source}: no such filter file")
        if isinstance(source, Path):
            check_user_file(source, what="filter file", cap=MAX_SOURCE_BYTES, error=FilterLoadError)
        if path is None or not _is_team_file(path, cls_name):
            try:
                results = run_checks(args.filter, load_scenario(args.scenario), sandbox=sandbox)
            except SandboxError as exc:
                raise FilterLoadError(str(exc)) from None
            print_report(args.filter, results)
            return 0 if all(r.passed for r in results) else 1
    cls = load_filter_class(args.filter)  # FilterLoadError: one line, exit status 2
    if callable(getattr(cls, "estimates", None)) and not callable(getattr(cls, "estimate", None)):
        name = args.scenario if is_team_scenario(args.scenario) else "team_sparse"
        results = run_team_checks(args.filter, cls, load_team_scenario(name))
        print_report(args.filter, results)
        return 0 if all(r.passed for r in results) else 1
    scenario = load_scenario(args.scenario)
    results = run_checks(args.filter, scenario, isolated=sandbox != "none")
    print_report(args.filter, results)
    return 0 if all(r.passed for r in results) else 1
