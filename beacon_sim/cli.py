"""The ``beacon-sim`` command line (design.md section 8).

Bad arguments or files give a one-line message, exit status 2 and no traceback.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import Any

from beacon_sim import __version__


class UsageError(Exception):
    """A one-line message for the user; the command exits with status 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, exit 2, no usage dump
        raise UsageError(f"{self.prog}: {message} (see {self.prog} --help)")


def _add_filter_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--filter", action="append", metavar="F", dest="filters",
                   help="filter to run: built-in name, pkg.mod:Class or file.py:Class "
                        "(repeat for several; default: the scenario's default_filters)")
    p.add_argument("--set", action="append", default=[], metavar="NAME.KEY=VALUE",
                   dest="set_params", help="override a filter parameter, e.g. pf.n_particles=1000")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="beacon-sim", description="Drive a robot among beacons and watch "
                     "Bayesian filters localise it. With no command: play the default scenario.")
    parser.add_argument("--version", action="version", version=f"beacon-sim {__version__}")
    sub = parser.add_subparsers(dest="command", parser_class=_Parser)

    p = sub.add_parser("play", help="open the simulator window")
    p.add_argument("scenario", nargs="?", default="default")
    _add_filter_options(p)
    p.add_argument("--seed", type=int)
    p.add_argument("--no-record", action="store_true", help="do not record this session")
    p.add_argument("--frames", type=int, help="quit after N frames (for scripts and tests)")
    p.add_argument("--screenshot", metavar="PNG", help="save the last frame to PNG")
    p.add_argument("--size", default="1280x800", help="window size WxH in pixels")
    p.add_argument("--autopilot", action="store_true",
                   help="start with the scenario's driver at the wheel (M toggles it)")

    p = sub.add_parser("run", help="one headless run; prints a summary")
    p.add_argument("scenario")
    _add_filter_options(p)
    p.add_argument("--seed", type=int)
    p.add_argument("--duration", type=float, metavar="S", help="seconds to simulate")
    p.add_argument("--json", action="store_true", help="print one JSON object")

    p = sub.add_parser("check", help="conformance report for a filter")
    p.add_argument("filter")
    p.add_argument("--scenario", default="default")

    sub.add_parser("list", help="shipped scenarios and available filters")

    # --- eval (issue 7; owner: beacon_sim/evaluation/) ---
    p = sub.add_parser("eval", help="Monte Carlo comparison of filters over seeds")
    p.add_argument("scenarios", nargs="+", metavar="SCENARIO")
    _add_filter_options(p)
    p.add_argument("--runs", type=int, default=20)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--duration", type=float, metavar="S")
    p.add_argument("--jobs", type=int, help="parallel processes (default: all cores)")
    p.add_argument("--out", metavar="DIR", help="write CSV, JSON and PNG plots here")
    p.add_argument("--json", action="store_true")
    p.add_argument("--no-batch", action="store_true",
                   help="run the filters one run at a time (default: batched across runs when possible)")

    # --- replay / export / mrclam (issue 6; owner: beacon_sim/recording.py, replay.py, ...) ---
    p = sub.add_parser("replay", help="replay a recording bit for bit, with any filters")
    p.add_argument("file")
    _add_filter_options(p)
    p.add_argument("--headless", action="store_true")
    p.add_argument("--json", action="store_true")
    p.add_argument("--frames", type=int, help="on screen: quit after N frames of 1/60 s")
    p.add_argument("--screenshot", metavar="PNG", help="on screen: save the last frame to PNG")

    p = sub.add_parser("export", help="export a recording as arrays (.npz or .csv)")
    p.add_argument("file")
    p.add_argument("--out", required=True, metavar="PATH")

    p = sub.add_parser("mrclam", help="replay a UTIAS MRCLAM data set folder")
    p.add_argument("dir")
    p.add_argument("--robot", type=int, required=True)
    _add_filter_options(p)
    p.add_argument("--headless", action="store_true")
    p.add_argument("--json", action="store_true")
    p.add_argument("--duration", type=float, metavar="S", help="only the first S seconds")
    p.add_argument("--calibrate", action="store_true",
                   help="print the noise settings estimated from the data and stop")
    p.add_argument("--frames", type=int, help="quit the window after N frames (for scripts and tests)")
    p.add_argument("--screenshot", metavar="PNG", help="save the window's last frame to PNG")

    # --- new-filter (issue 8) ---
    p = sub.add_parser("new-filter", help="write a working, commented filter template")
    p.add_argument("path")
    return parser


def _load(name: str):
    from beacon_sim.core.scenario import load_scenario

    return load_scenario(name)


def _filter_params(args) -> dict[str, dict[str, Any]]:
    from beacon_sim.filters.loading import parse_set_options

    return parse_set_options(args.set_params)


def cmd_run(args) -> int:
    from beacon_sim.headless import run_headless

    scenario = _load(args.scenario)
    if args.duration is not None and not (args.duration > 0 and math.isfinite(args.duration)):
        raise UsageError(f"--duration {args.duration}: expected a positive number of seconds")
    result = run_headless(scenario, args.filters, seed=args.seed, duration=args.duration,
                          params=_filter_params(args))
    _print_sensor_notes(args.filters or scenario.default_filters, scenario)
    data = result.as_json()
    if args.json:
        print(json.dumps(data, indent=None, default=float))
    else:
        _print_run(data)
    for track in result.runner.tracks.values():
        if track.failed:
            print(f"filter {track.name} failed: {track.failed}\n{track.traceback}",
                  file=sys.stderr)
    return 0


def _print_sensor_notes(specs, scenario) -> None:
    """Tell the user, on stderr, about filters that can use none of the scenario's sensors."""
    from beacon_sim.filters.loading import FilterLoadError, sensor_note

    for spec in specs:
        try:
            note = sensor_note(spec, scenario)
        except FilterLoadError:
            continue
        if note:
            print(note, file=sys.stderr)


def _fmt(x: float, spec: str) -> str:
    """A figure for the table; huge ones (ANEES after a kidnap) in exponent form."""
    return format(x, spec) if abs(x) < 1e5 else format(x, ".2e")


def _print_run(d: dict) -> None:
    print(f"scenario {d['scenario']}  seed {d['seed']}  steps {d['steps']} "
          f"({d['sim_time_s']:g} s simulated)  distance {d['distance_m']:.2f} m")
    meas = ", ".join(f"{k}: {v}" for k, v in d["measurements"].items()) or "none"
    print(f"measurements  {meas}")
    ev = ", ".join(f"{e['kind']} at {e['time']:.2f} s" for e in d["events"]) or "none"
    print(f"events        {ev}")
    print(f"truth checksum {d['truth_checksum']}  ({d['steps_per_s']:.0f} simulation steps/s)")
    if d["filters"]:
        print(f"{'filter':<16}{'pos RMSE m':>11}{'head RMSE':>11}{'MSE x':>10}{'MSE y':>10}"
              f"{'MSE th':>10}{'ANEES':>9}{'us/step':>9}")
        for name, r in d["filters"].items():
            if "failed" in r:
                print(f"{name:<16}FAILED: {r['failed']}")
                continue
            print(f"{name:<16}{r['pos_rmse_m']:>11.4f}{r['heading_rmse_rad']:>11.4f}"
                  f"{r['mse_x']:>10.4f}{r['mse_y']:>10.4f}{r['mse_theta']:>10.4f}"
                  f"{_fmt(r['anees'], '.2f'):>9}{r['us_per_step']:>9.1f}")


def cmd_list(args) -> int:
    from beacon_sim.core.scenario import load_scenario
    from beacon_sim.filters.loading import available_filters
    from beacon_sim.resources import shipped_scenarios

    print("scenarios:")
    for name in shipped_scenarios():
        print(f"  {name:<22}{load_scenario(name).description}")
    print("filters:")
    for name in available_filters():
        print(f"  {name}")
    return 0


def cmd_check(args) -> int:
    from beacon_sim.filters.conformance import print_report, run_checks

    results = run_checks(args.filter, _load(args.scenario))
    print_report(args.filter, results)
    return 0 if all(r.passed for r in results) else 1


def cmd_play(args) -> int:
    from beacon_sim.app.main import play

    return play(args)


def _lazy(target: str):
    """A command implemented in another module, imported only when used."""

    def command(args) -> int:
        import importlib

        module, _, func = target.partition(":")
        return getattr(importlib.import_module(module), func)(args)

    return command


COMMANDS = {
    "run": cmd_run,
    "list": cmd_list,
    "check": cmd_check,
    "play": cmd_play,
    "eval": _lazy("beacon_sim.evaluation.command:eval_command"),
    "replay": _lazy("beacon_sim.replay:replay_command"),
    "export": _lazy("beacon_sim.replay:export_command"),
    "mrclam": _lazy("beacon_sim.mrclam:mrclam_command"),
    "new-filter": _lazy("beacon_sim.filters.template:new_filter_command"),
}


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``beacon-sim`` console script."""
    from beacon_sim.core.scenario import ScenarioError
    from beacon_sim.filters.base import FilterError

    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        parser = build_parser()
        args = parser.parse_args(argv or ["play"])
        return COMMANDS[args.command](args)
    except (UsageError, ScenarioError, FilterError) as exc:
        print(f"beacon-sim: {exc}" if not str(exc).startswith("beacon-sim") else str(exc),
              file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    raise SystemExit(main())
