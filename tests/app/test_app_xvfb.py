"""Smoke test in a real X window: start ``beacon-sim`` under Xvfb, let it run, take a
screenshot, quit cleanly. Skipped where Xvfb is not installed (CI installs Debian's xvfb)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.skipif(shutil.which("Xvfb") is None, reason="Xvfb is not installed")


@pytest.fixture
def display():
    proc = subprocess.Popen(["Xvfb", "-displayfd", "1", "-screen", "0", "1400x900x24", "-nolisten", "tcp"],
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    try:
        line = proc.stdout.readline().decode().strip()  # Xvfb prints its display number when ready
        if not line.isdigit():
            pytest.fail(f"Xvfb did not start: {line!r}")
        yield f":{line}"
    finally:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()


def test_window_under_xvfb_runs_screenshots_and_quits(display, tmp_path):
    env = dict(os.environ)
    env.pop("SDL_VIDEODRIVER", None)  # a real (X11) window, not the dummy driver
    env.update(DISPLAY=display, SDL_FRAMEBUFFER_ACCELERATION="0", SDL_AUDIODRIVER="dummy",
               PYGAME_HIDE_SUPPORT_PROMPT="1")
    shot = tmp_path / "xvfb.png"
    script = Path(sys.executable).parent / "beacon-sim"  # the installed console script
    exe = [str(script)] if script.exists() else [sys.executable, "-m", "beacon_sim"]
    cmd = [*exe, "play", "default", "--filter", "dead_reckoning",
           "--frames", "90", "--screenshot", str(shot), "--no-record"]
    done = subprocess.run(cmd, env=env, cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    import pygame

    img = pygame.image.load(str(shot))
    assert img.get_size() == (1280, 800)
    # Something was drawn: the picture is not one flat colour.
    colours = {tuple(img.get_at((x, y))) for x in range(0, 1280, 40) for y in range(0, 800, 40)}
    assert len(colours) > 3
