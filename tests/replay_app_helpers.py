"""A recorded hand-driven session and a scripted replay window of it, for the replay window tests."""

from __future__ import annotations

import pygame

from beacon_sim.app.replay import ReplayApp
from beacon_sim.io.recording import load_recording
from beacon_sim.runs.replay import ReplaySession

TICKS = 320  # 16 s at dt = 0.05


FILTERS = ["ekf", "dead_reckoning"]



def key(k):
    pygame.event.post(pygame.event.Event(pygame.KEYDOWN, key=k, mod=0, unicode="", scancode=0))
    pygame.event.post(pygame.event.Event(pygame.KEYUP, key=k, mod=0, unicode="", scancode=0))


def make(path, size=(960, 600)) -> ReplayApp:
    return ReplayApp(ReplaySession(load_recording(path), FILTERS), size=size, scripted=True)


def run_until(app, tick, limit=5000):
    while app.session.sim.tick < tick and app.frames < limit:
        app.run(app.frames + 1)

