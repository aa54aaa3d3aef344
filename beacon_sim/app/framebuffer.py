"""Which way SDL puts a frame on the screen, picked for the display before a window opens.

SDL shows a window's surface either through its video driver's own framebuffer (on X11:
shared-memory images) or through a texture its renderer draws (OpenGL). On a plain X server
(no GPU: Xvfb, a virtual machine, a remote desktop) the texture is drawn by software OpenGL,
and at 1920x1080 a flip took 44 ms against 3.9 ms for X11's own framebuffer (the default view
at 15 against 53 FPS, docs/window.md). The window takes X11's own framebuffer there unless
``SDL_FRAMEBUFFER_ACCELERATION`` is set (``1``: SDL's texture, ``0``: its own framebuffer).
"""

from __future__ import annotations

import os
from collections.abc import MutableMapping

#: SDL's hint (read from the environment when a window's surface is made).
ENV = "SDL_FRAMEBUFFER_ACCELERATION"

#: Video drivers whose own framebuffer was measured faster than SDL's texture there.
NATIVE_FASTER = frozenset({"x11"})


def choose_framebuffer(driver: str, environ: MutableMapping[str, str] | None = None) -> str:
    """Set SDL's framebuffer hint for the video driver ``driver`` (``pygame.display.get_driver()``,
    after ``pygame.display.init()``, before ``set_mode``) and say what was chosen:
    ``"native"`` (the driver's own framebuffer), ``"as set"`` (the user's
    ``SDL_FRAMEBUFFER_ACCELERATION``, left alone) or ``"SDL's choice"`` (any other driver)."""
    env = os.environ if environ is None else environ
    if env.get(ENV, "").strip():
        return "as set"
    if driver in NATIVE_FASTER:
        env[ENV] = "0"
        return "native"
    return "SDL's choice"


__all__ = ["ENV", "NATIVE_FASTER", "choose_framebuffer"]
