"""The window picks SDL's framebuffer path itself: X11's own framebuffer on X11 (measured
faster under a plain X server, docs/window.md), the user's SDL_FRAMEBUFFER_ACCELERATION left
as set, other drivers left to SDL. Whether it is faster is a benchmark's question, not
this test's: here, that the choice is made before the window opens."""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import pygame

from beacon_sim.app import framebuffer
from beacon_sim.app.framebuffer import ENV, choose_framebuffer
from beacon_sim.app.window import App
from beacon_sim.core.scenario import load_scenario
from beacon_sim.runs.live import Session


def test_x11_takes_its_own_framebuffer_unless_the_user_said():
    env: dict[str, str] = {}
    assert choose_framebuffer("x11", env) == "native"
    assert env == {ENV: "0"}
    for said in ("1", "0", "opengl"):
        env = {ENV: said}
        assert choose_framebuffer("x11", env) == "as set"
        assert env == {ENV: said}
    for driver in ("wayland", "windows", "cocoa", "dummy", "offscreen"):
        env = {}
        assert choose_framebuffer(driver, env) == "SDL's choice"
        assert env == {}


def test_the_window_sets_the_hint_before_its_surface_is_made(monkeypatch):
    monkeypatch.delenv(ENV, raising=False)
    monkeypatch.setattr(pygame.display, "get_driver", lambda: "x11")
    seen = []
    set_mode = pygame.display.set_mode

    def spy(*args, **kwargs):
        seen.append(os.environ.get(ENV))
        return set_mode(*args, **kwargs)

    monkeypatch.setattr(pygame.display, "set_mode", spy)
    app = App(Session(load_scenario("default"), ["ekf"]), (640, 400), scripted=True)
    try:
        assert app.framebuffer == "native"
        assert seen == ["0"]  # set when the window's surface was made
    finally:
        app.close()
    monkeypatch.setenv(ENV, "1")
    app = App(Session(load_scenario("default"), ["ekf"]), (640, 400), scripted=True)
    try:
        assert app.framebuffer == "as set" and os.environ[ENV] == "1"
    finally:
        app.close()
    assert framebuffer.NATIVE_FASTER == {"x11"}
