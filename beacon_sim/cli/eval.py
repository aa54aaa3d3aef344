"""``beacon-sim eval SCENARIO ... [--filter F ...] [--runs N] [--seed S] [--jobs J]
[--scheduler ADDRESS] [--out DIR] [--json] [--strict]``: Monte Carlo comparison of
filters, with the PCRB (``--scheduler``: on a Dask cluster, the same results).

Prints a table per scenario (or one JSON object with ``--json``); with ``--out DIR`` also
writes the files of :func:`beacon_sim.evaluation.report.write_outputs`. A filter that
failed in any run gets no score (``FAILED``); ``--strict`` makes that exit status 1.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from beacon_sim.cli.common import check_duration
from beacon_sim.core.arguments import check_simulated_total
from beacon_sim.core.optional import install_hint
from beacon_sim.core.scenario import is_team_scenario, load_scenario, load_team_scenario
from beacon_sim.errors import UsageError
from beacon_sim.evaluation.montecarlo import (
    ClusterError,
    RunOutput,
    dask_client,
    run_monte_carlo,
    run_monte_carlo_isolated,
    run_team_monte_carlo,
)
from beacon_sim.evaluation.report import table_lines, write_outputs
from beacon_sim.evaluation.smoothing_run import smoothing_monte_carlo
from beacon_sim.evaluation.smoothing_run import table_lines as smoothing_lines
from beacon_sim.evaluation.summary import Evaluation, Thresholds
from beacon_sim.evaluation.team_summary import evaluate_team, team_table_lines, write_team_outputs
from beacon_sim.filters.base import FilterError
from beacon_sim.hosting.containment import SandboxError
from beacon_sim.hosting.loading import (
    FilterLoadError,
    build_filter,
    check_param_names,
    filter_display_name,
    filter_names,
    parse_set_options,
    sensor_note,
)
from beacon_sim.hosting.runner import HEADLESS_STEP_LIMIT_S, exit_text, is_filter_failure
from beacon_sim.hosting.sources import hosted_source
from beacon_sim.hosting.team_specs import check_team_specs
from beacon_sim.runs.headless import SLOW_CPU_PER_SIM_S, slow_note
from beacon_sim.runs.smoothing import smoothable

#: Each filter's time limit per run when ``--time-limit`` is not given [s]: a filter stuck
#: in a loop is stopped and marked, the evaluation goes on.
DEFAULT_RUN_LIMIT_S = 300.0


def _validate(args: argparse.Namespace) -> None:
    if args.runs is None or args.runs < 1:
        raise UsageError(f"--runs {args.runs}: expected a whole number of runs >= 1")
    if args.jobs is not None and args.jobs < 1:
        raise UsageError(f"--jobs {args.jobs}: expected a number of processes >= 1")
    if args.seed is not None and args.seed < 0:
        raise UsageError(f"--seed {args.seed}: expected a seed >= 0")
    if args.duration is not None and not (args.duration > 0 and math.isfinite(args.duration)):
        raise UsageError(f"--duration {args.duration}: expected a positive number of seconds")
    limit = getattr(args, "time_limit", None)
    if limit is not None and not (limit > 0 and math.isfinite(limit)):
        raise UsageError(f"--time-limit {limit}: expected a positive number of seconds")
    if args.out is not None and Path(args.out).exists() and not Path(args.out).is_dir():
        raise UsageError(f"--out {args.out}: exists and is not a folder")


def _isolated(args: argparse.Namespace) -> bool:
    """Whether filter files run in processes of their own (the default; ``--sandbox none``:
    in this process, as before)."""
    return getattr(args, "sandbox", None) != "none"


def eval_command(args: argparse.Namespace) -> int:
    """Run the evaluation the parsed ``args`` ask for; returns the exit status. Team
    scenarios (``[[robots]]``) are evaluated by :func:`team_metas`, single robots here; the
    document, the files and the failures are the same code for both."""
    _validate(args)
    team = [is_team_scenario(s) for s in args.scenarios]
    if any(team):
        if getattr(args, "scheduler", None) is not None:
            raise UsageError("eval --scheduler: team scenarios run locally only (use --jobs)")
        if not all(team):
            raise UsageError("eval: team scenarios and single-robot scenarios in one evaluation; "
                             "evaluate them in two commands")
        metas = team_metas(args)
        document = metas[0] if len(metas) == 1 else {"scenarios": metas}
        if args.json:
            print(json.dumps(document, default=float))
        if args.out is not None:
            write_team_outputs(Path(args.out), metas, document)
        return _failures(args, metas)
    params = parse_set_options(getattr(args, "set_params", []) or [])
    scenarios = [load_scenario(s) for s in args.scenarios]
    for sc in scenarios:
        check_duration(args.duration, sc)  # (a duration of too many ticks says so first)
    check_simulated_total(args.runs * len(scenarios),
                          max(args.duration or sc.duration for sc in scenarios),
                          f"eval --runs {args.runs}", UsageError)
    for sc in scenarios:  # bad filter names and parameters: a one-line error, before any run
        specs = list(args.filters or sc.default_filters)
        check_param_names(params, specs)
        for name, spec in zip(filter_names(specs), specs, strict=True):
            where = hosted_source(spec) if _isolated(args) else None
            if where is not None:  # a file or module: its code runs in its own process only
                if isinstance(where[0], Path) and not where[0].is_file():
                    raise FilterLoadError(f"{where[0]}: no such filter file")
                continue
            try:
                build_filter(spec, sc, 0, name=name, params=params.get(filter_display_name(spec)))
            except FilterError:
                raise  # a name or parameter that cannot work: one line, exit 2
            except BaseException as exc:  # a student's __init__ raises: the runs mark it FAILED
                if not is_filter_failure(exc):
                    raise
        check_duration(args.duration, sc)
    out = Path(args.out) if args.out else None
    client, own = _connect(getattr(args, "scheduler", None))
    try:
        results = _evaluate_all(args, scenarios, params, client)
    finally:
        if own:
            client.close()
    metas = [m for _, m, _ in results]
    document = metas[0] if len(metas) == 1 else {"scenarios": metas}
    if args.json:
        print(json.dumps(document, default=float))
    if out is not None:
        write_outputs(out, results, document)
    return _failures(args, metas)


def _failures(args: argparse.Namespace, metas: list[dict[str, Any]]) -> int:
    """Say on stderr which filter failed in how many runs of which scenario (no score); the
    exit status: 1 for a failure under ``--strict``, else 0."""
    failed = {(m["scenario"], name): r["failed_runs"] for m in metas
              for name, r in m["filters"].items() if r.get("failed_runs")}
    for (scenario, name), n in failed.items():
        print(f"beacon-sim eval: {name} failed in {n} run(s) of {scenario} (no score)",
              file=sys.stderr)
    return 1 if failed and getattr(args, "strict", False) else 0


def _connect(address: str | None) -> tuple[Any, bool]:
    """A Dask client for ``--scheduler ADDRESS`` (None: none) and whether to close it; a
    bad address or an unreachable scheduler is one line, exit status 2."""
    if address is None:
        return None, False
    if "://" not in address:
        raise UsageError(f"--scheduler {address}: expected a Dask scheduler address such as "
                         "tcp://host:8786")
    try:
        import dask.distributed  # noqa: F401
    except ImportError:
        raise UsageError(install_hint("dask", "--scheduler")) from None
    try:
        return dask_client(address)
    except (OSError, TimeoutError, ValueError) as exc:
        why = str(exc).strip().splitlines()
        raise UsageError(f"--scheduler {address}: cannot reach the Dask scheduler "
                         f"({why[0] if why else type(exc).__name__})") from None


def _evaluate_all(args: argparse.Namespace, scenarios: list[Any], params: dict[str, dict[str, Any]],
                  scheduler: Any) -> list[tuple[Any, dict[str, Any], Any]]:
    """Every scenario's runs (locally, or on Dask) and its summary."""
    results = []
    for sc in scenarios:
        specs = list(args.filters or sc.default_filters)
        try:
            limit = getattr(args, "time_limit", None) or DEFAULT_RUN_LIMIT_S
            batch = False if getattr(args, "no_batch", False) else None
            ev = Evaluation(sc, Thresholds())
            take = _saying_if_slow(ev, sc, args.runs, args.duration or sc.duration)
            if _isolated(args) and any(hosted_source(s) is not None for s in specs):
                # a hosted filter's runs are fed from simulations kept for them: not streamed
                for run in run_monte_carlo_isolated(sc, specs, args.runs, seed=args.seed or 0,
                                                    duration=args.duration, jobs=args.jobs, params=params,
                                                    run_limit_s=limit, sandbox=args.sandbox or "auto",
                                                    batch=batch, scheduler=scheduler):
                    take(run)
            else:   # each run reduced as it ends and dropped: memory does not grow with --runs
                run_monte_carlo(sc, specs, args.runs, seed=args.seed or 0, duration=args.duration,
                                jobs=args.jobs, params=params, batch=batch, run_limit_s=limit,
                                scheduler=scheduler, on_run=take, keep_runs=False)
        except (SandboxError, ClusterError) as exc:
            raise UsageError(str(exc)) from None
        except (SystemExit, KeyboardInterrupt) as exc:
            # Raised by a filter's code inside the Monte Carlo loop (which switches off only
            # filters that raise an Exception): never a silent exit, and never status 0.
            if not is_filter_failure(exc):
                raise
            what = exit_text(exc).removesuffix(" raised by the filter")
            raise UsageError(f"{sc.name}: a filter's code raised {what} during the evaluation; "
                             "run it alone with beacon-sim run to see which") from None
        meta, curves = ev.result()
        smoothed = _smoothed(args, sc, specs, params)
        if smoothed:
            meta["smoothing"] = smoothed
        results.append((sc, meta, curves))
        if not args.json:
            print("\n".join(table_lines(meta)))
            if smoothed:
                print("\n".join(smoothing_lines(smoothed)))
            for spec in specs:   # a filter the scenario's sensors cannot feed: say so, as run does
                note = sensor_note(spec, sc)
                if note:
                    print(note)
            print()
    return results


def _saying_if_slow(ev: Evaluation, sc: Any, runs: int, duration: float) -> Callable[[RunOutput], None]:
    """``ev.add_any`` that says once, on stderr, when a filter takes more than
    ``SLOW_CPU_PER_SIM_S`` seconds of filter time per simulated second of a run."""
    said = False

    def take(run: RunOutput) -> None:
        nonlocal said
        if not said:
            for name, fr in run.filters.items():
                per = fr.step_ns / 1e9 / max(fr.steps * sc.dt, 1e-9)
                if per > SLOW_CPU_PER_SIM_S:
                    print(slow_note(f"filter {name}", per, runs * duration, what="filter time"),
                          file=sys.stderr)
                    said = True
                    break
        ev.add_any(run)

    return take


def _smoothed(args: argparse.Namespace, sc: Any, specs: list[str],
              params: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """``--smooth``: each EKF/UKF of the evaluation filtered and smoothed over the same seeds
    (``evaluation/smoothing_run.py``), by filter name; empty without ``--smooth``."""
    if not getattr(args, "smooth", False):
        return {}
    seeds = range(args.seed or 0, (args.seed or 0) + args.runs)
    out = {}
    for spec in specs:
        if smoothable(spec):
            name = filter_display_name(spec)
            out[name] = smoothing_monte_carlo(sc, spec, seeds, args.duration, params.get(name))
    if not out:
        print(f"note: --smooth: no filter of {sc.name} can be smoothed (ekf, ukf)", file=sys.stderr)
    return out


def team_metas(args: argparse.Namespace) -> list[dict[str, Any]]:
    """``eval`` on team scenarios: team filters (``--filter``, default the scenario's), a row
    per robot and the team's, the joint PCRB (``team_summary.evaluate_team``); each scenario's
    table printed unless ``--json``. ``--time-limit S``: a filter's time limit per run, as
    for a single robot; ``--no-batch`` changes nothing (team runs are not batched)."""
    params = parse_set_options(getattr(args, "set_params", []) or [])
    teams = [load_team_scenario(s) for s in args.scenarios]
    for team in teams:  # bad names and parameters: one line, exit 2, before any run
        check_team_specs(list(args.filters or team.default_filters), team, params)
        check_duration(args.duration, team.robots[0].scenario)
    metas = []
    for team in teams:
        runs = run_team_monte_carlo(team, list(args.filters or team.default_filters), args.runs,
                                    seed=args.seed or 0, duration=args.duration, jobs=args.jobs,
                                    params=params, step_limit_s=HEADLESS_STEP_LIMIT_S,
                                    run_limit_s=getattr(args, "time_limit", None) or DEFAULT_RUN_LIMIT_S)
        meta = evaluate_team(team, runs)
        metas.append(meta)
        if not args.json:
            print("\n".join(team_table_lines(meta)))
            print()
    return metas
