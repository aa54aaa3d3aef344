"""``beacon-sim mrclam DIR --robot N`` on screen: a finished MRCLAM run
(:class:`beacon_sim.runs.mrclam.MrclamPlayback`: ground truth, landmarks, readings and the
filters' estimates) played back in the replay window, with its timeline.
"""

from __future__ import annotations

import os
import sys

import pygame

from beacon_sim.app.replay import ReplayApp
from beacon_sim.runs.mrclam import MrclamPlayback, MrclamRun


def show_mrclam(run: MrclamRun, frames: int | None = None, screenshot: str | None = None,
                size: tuple[int, int] = (1280, 800)) -> int:
    """The window over a finished MRCLAM run, ``size`` (W, H) [px], until quit (or ``frames``
    frames of 1/60 s); ``screenshot`` saves the last frame. Without a display it says so and returns 0 (the
    table printed before is the result)."""
    from beacon_sim.app.display import check_display
    from beacon_sim.errors import UsageError

    os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
    try:
        check_display()  # a DISPLAY with no server: say so rather than draw invisibly
    except UsageError as exc:
        print(f"note: {exc}; results above are headless", file=sys.stderr)
        return 0
    try:
        app = ReplayApp(MrclamPlayback(run), size, scripted=frames is not None)
    except pygame.error as exc:
        print(f"note: cannot open a window ({exc}); results above are headless", file=sys.stderr)
        return 0
    try:
        app.run(frames)
        if screenshot:
            app.save_screenshot(screenshot)
    finally:
        app.close()
    print(f"mrclam: shown up to t = {app.session.time:.1f} s of "
          f"{run.t_end - run.t_start:.1f} s", file=sys.stderr)
    return 0


__all__ = ["show_mrclam"]
