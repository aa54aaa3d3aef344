"""The display a window opens on: is there one (a headless machine says so in one line, exit 2,
rather than draw invisibly), and the window's surface once it is open.
"""

from __future__ import annotations

import os
import sys

import pygame


def display_surface() -> pygame.Surface:
    """The window's surface (``set_mode`` made it; None only once the display is closed)."""
    surf = pygame.display.get_surface()
    if surf is None:
        raise pygame.error("the window's display surface is gone")
    return surf


def check_display() -> None:
    """Raise ``UsageError`` (one line, exit 2) when no window can open: on Linux, no X or
    Wayland display and no SDL video driver chosen (a window would run invisibly)."""
    from beacon_sim.errors import UsageError

    if os.environ.get("SDL_VIDEODRIVER"):
        return
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY")
                                                 or os.environ.get("WAYLAND_DISPLAY")):
        raise UsageError("no display to open a window on (DISPLAY is not set); for a headless"
                         " window set SDL_VIDEODRIVER=dummy, or use beacon-sim run")
    try:
        pygame.display.init()
    except pygame.error as exc:
        raise UsageError(f"cannot open a window: {exc}") from None
    driver = pygame.display.get_driver()
    if driver in HEADLESS_DRIVERS:  # SDL fell back to drawing nowhere: DISPLAY has no server
        pygame.display.quit()
        where = os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY") or "the display"
        raise UsageError(f"cannot open a window on {where} (no display server answers there;"
                         " SDL would draw invisibly); for a headless window set"
                         " SDL_VIDEODRIVER=dummy, or use beacon-sim run")


#: SDL video drivers that show nothing; chosen only by SDL_VIDEODRIVER, never as a fallback.
HEADLESS_DRIVERS = frozenset({"offscreen", "dummy"})
