"""``beacon-sim play``: open the window (``window.App``) on a live session, one robot or a team,
run it as the command line asked (paused, speed, GIF, ``--frames``, ``--screenshot``) and
close it. The replay window (``beacon-sim replay``) starts and ends through :func:`start` and
:func:`finish_gif` too.
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass, field
from typing import Any

from beacon_sim.app.display import check_display
from beacon_sim.app.window import SCRIPTED_FRAME_S, App
from beacon_sim.core.scenario import Scenario, TeamScenario
from beacon_sim.runs.live import Session, make_recorder


@dataclass(frozen=True)
class PlayOptions:
    """What ``beacon-sim play`` opens (the command line checks and builds these)."""

    scenario: Scenario | TeamScenario  # one robot, or a team (Tab drives the next robot)
    filters: list[str]  # filter specs
    seed: int
    params: dict[str, dict[str, Any]] = field(default_factory=dict)  # ``--set`` overrides
    size: tuple[int, int] = (1280, 800)  # window [px]
    frames: int | None = None  # quit after this many frames (scripts, tests)
    screenshot: str | None = None  # save the last frame here (PNG)
    record: bool = True
    autopilot: bool = False
    paused: bool = False  # start paused (Space runs, . steps)
    speed: float | None = None  # start at this speed factor (nearest of loop.SPEEDS)
    gif: str | None = None  # also write the session as an animated GIF here
    gif_width: int | None = 640  # the GIF's width [px]; None: the window's
    foxglove: int | None = None  # also stream the session to Foxglove on this port (127.0.0.1)


def play(options: PlayOptions) -> int:
    """Open the window on a live session (one robot or a team); returns the exit status."""
    o = options
    check_display()
    recorder, rec_path = (None, None)
    if o.record:
        recorder, rec_path = make_recorder(o.scenario, o.seed, o.filters, o.params)
    session = Session(o.scenario, o.filters, o.seed, o.params, recorder)
    if o.autopilot:
        session.toggle_autopilot()
    os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
    app = App(session, o.size, scripted=o.frames is not None, recording=rec_path)
    from beacon_sim.app.foxglove import stream

    live = stream(session, o.foxglove)
    if live is not None:  # the stream reads the filters' tracks after each tick: in the tick
        app.filter_thread = False
    try:
        run_window(app, o)
    finally:
        if live is not None:
            live.close()
    if rec_path is not None:
        print(f"recorded to {rec_path}", file=sys.stderr)
    return 0


def run_window(app: App, options: PlayOptions) -> None:
    """Run an opened window as the command line asked (paused, speed, GIF, ``--frames``),
    save ``--screenshot`` from its last frame and the GIF, and close it."""
    o = options
    start(app, o.paused, o.speed, o.gif, o.gif_width)
    try:
        app.run(o.frames)
        if o.screenshot:
            app.save_screenshot(o.screenshot)
        finish_gif(app)
    finally:
        app.close()


def start(app: App, paused: bool = False, speed: float | None = None, gif: str | None = None,
          gif_width: int | None = 640) -> None:
    """The command line's starting state: paused, the speed factor, a GIF being captured
    (``gif_width`` [px] wide; None: as wide as the window)."""
    if paused:
        app.clock.paused = True
    if speed is not None:
        app.clock.set_speed(speed)
    if gif:
        from beacon_sim.app.gif import GifRecorder

        app.gif = GifRecorder(gif, width=gif_width or app.screen.get_width())


def finish_gif(app: App) -> None:
    """Write the GIF the window captured (if any) and say where, how many frames, how big."""
    if app.gif is None:
        return
    n = app.gif.save()
    size = app.gif.size  # set by the first frame captured
    if not n or size is None:
        print(f"beacon-sim: no frame captured, {app.gif.path} not written", file=sys.stderr)
        return
    kb = app.gif.path.stat().st_size / 1024
    full = " (stopped capturing at the frame limit)" if app.gif.full else ""
    print(f"wrote {app.gif.path}: {n} frames of {app.gif.duration_ms} ms, {size[0]}x"
          f"{size[1]} px, {kb:.0f} KB{full}", file=sys.stderr)


# App and SCRIPTED_FRAME_S are still importable from here (scripts, benchmarks and tests name them).
__all__ = ["SCRIPTED_FRAME_S", "App", "PlayOptions", "finish_gif", "play", "run_window", "start"]
