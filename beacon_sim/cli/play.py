"""``beacon-sim play [SCENARIO] ...`` (and plain ``beacon-sim``): open the simulator window."""

from __future__ import annotations

import argparse
import sys

from beacon_sim.cli.common import check_frames, check_set_names, filter_params, print_sensor_notes
from beacon_sim.core.optional import install_hint
from beacon_sim.core.scenario import Scenario, load_any_scenario
from beacon_sim.errors import UsageError
from beacon_sim.hosting.loading import WINDOW_BUILD_LIMIT_S, FilterLoadError, load_filter_class
from beacon_sim.hosting.team_specs import check_team_specs

#: The smallest window [px] everything fits in (the panel's lines, the help overlay).
MIN_SIZE = (800, 600)
MAX_SIDE = 10000


def parse_size(text: str) -> tuple[int, int]:
    """``--size WxH`` [px]: at least :data:`MIN_SIZE`, at most 10000 each."""
    w, sep, h = text.lower().partition("x")
    try:
        size = (int(w), int(h))
    except ValueError:
        size = (0, 0)
    if not sep or min(size) <= 0:
        raise UsageError(f"--size {text!r}: expected WxH in pixels, e.g. 1280x800")
    if size[0] < MIN_SIZE[0] or size[1] < MIN_SIZE[1] or max(size) > MAX_SIDE:
        raise UsageError(f"--size {text}: the window must be at least {MIN_SIZE[0]}x{MIN_SIZE[1]} "
                         f"px (and at most {MAX_SIDE} a side), e.g. 1024x768 or 1920x1080")
    return size


def parse_gif_width(text: str) -> int | None:
    """``--gif-width PX`` (200 to 10000) or ``window`` (None: the window's width)."""
    if str(text).lower() == "window":
        return None
    try:
        width = int(text)
    except ValueError:
        width = 0
    if not 200 <= width <= MAX_SIDE:
        raise UsageError(f"--gif-width {text!r}: expected a width in pixels (200 to {MAX_SIDE}) "
                         "or 'window'")
    return width


def choose_filters(scenario: Scenario, requested: list[str] | None) -> list[str]:
    """The requested filters, or the scenario's defaults that are installed (missing
    built-ins are skipped with a note, so the window opens while filters are written)."""
    if requested:
        return list(requested)
    out = []
    for spec in scenario.default_filters:
        try:
            load_filter_class(spec)
        except FilterLoadError as exc:
            print(f"beacon-sim: skipping default filter {spec}: {exc}", file=sys.stderr)
            continue
        out.append(spec)
    return out


def play_command(args: argparse.Namespace) -> int:
    """``beacon-sim play [SCENARIO]``: the window on one robot, or on a team (a ``[[robots]]``
    file, whose ``--filter`` names team filter specs: Tab drives the next robot). Recorded
    unless ``--no-record``."""
    team = load_any_scenario(args.scenario or "default")
    size = parse_size(args.size)
    check_frames(args.frames)
    params = filter_params(args)
    if team.solo:
        scenario = team.robots[0].scenario
        specs = choose_filters(scenario, args.filters)
        check_set_names(args, specs)
        print_sensor_notes(specs, scenario)
    else:
        if getattr(args, "foxglove", None) is not None:
            raise UsageError("--foxglove: not for team scenarios yet (one robot only)")
        specs = list(args.filters or team.default_filters)
        check_team_specs(specs, team, params, WINDOW_BUILD_LIMIT_S)  # one line, exit 2, as in run
    if args.autopilot and all(r.scenario.driver.kind == "keyboard" for r in team.robots):
        raise UsageError(f"--autopilot: scenario {team.name} has no driver (driver.kind = keyboard)"
                         if team.solo else f"--autopilot: no robot of {team.name} has a driver")
    check_speed(args.speed)
    check_gif(args.gif)
    from beacon_sim.app.main import PlayOptions, play  # pygame only when a window opens

    return play(PlayOptions(team, specs, team.seed if args.seed is None else int(args.seed),
                            params, size, args.frames, args.screenshot, record=not args.no_record,
                            autopilot=args.autopilot, paused=args.paused, speed=args.speed,
                            gif=args.gif, gif_width=parse_gif_width(args.gif_width),
                            foxglove=check_foxglove(args) if team.solo else None))


def check_foxglove(args: argparse.Namespace) -> int | None:
    """``--foxglove [PORT]``: a port from 0 (any free one) to 65535, and foxglove-sdk installed
    (the ``mcap`` extra); returns the port or None."""
    port = getattr(args, "foxglove", None)
    if port is None:
        return None
    if not 0 <= port <= 65535:
        raise UsageError(f"--foxglove {port}: expected a port from 0 to 65535")
    try:
        import foxglove  # noqa: F401
    except ImportError:
        raise UsageError(install_hint("foxglove", "--foxglove")) from None
    return port


def check_speed(speed: float | None) -> None:
    """``--speed X``: a factor from 0.1 to 8 (the window takes the nearest of its steps)."""
    if speed is not None and not 0.1 <= speed <= 8.0:
        raise UsageError(f"--speed {speed:g}: expected a factor from 0.1 to 8")


def check_gif(path: str | None) -> None:
    """``--gif FILE``: a .gif name, and Pillow installed (the ``gif`` extra)."""
    if path is None:
        return
    if not path.lower().endswith(".gif"):
        raise UsageError(f"--gif {path!r}: expected a file name ending in .gif")
    try:
        import PIL  # noqa: F401
    except ImportError:
        raise UsageError(install_hint("PIL", "--gif")) from None
