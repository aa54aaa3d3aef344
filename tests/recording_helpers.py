"""A small scenario and a recorded live run of it, shared by the recording, replay and export tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.core.types import Control
from beacon_sim.hosting.loading import build_filter
from beacon_sim.hosting.runner import FilterRunner
from beacon_sim.runs.recorder import Recorder
from beacon_sim.runs.user_commands import apply_commands

SCENARIO = """
name = "rec_test"
dt = 0.1
duration = 30.0
seed = 3
default_filters = ["ekf", "dead_reckoning"]

[world]
bounds = [0.0, 0.0, 10.0, 10.0]
beacons = [{ id = 1, x = 2.0, y = 2.0 }, { id = 2, x = 8.0, y = 2.0 }, { id = 3, x = 5.0, y = 8.0 }]

[robot]
initial_pose = [5.0, 5.0, 0.0]
motion_noise = { v_std = 0.02, omega_std = 0.03, v_frac = 0.05 }

[[sensors]]
name = "rb"
kind = "range_bearing"
period = 0.2
max_range = 6.0
detection_prob = 0.8
range_std = 0.1
bearing_std = 0.05

[driver]
kind = "circle"
radius = 2.0
speed = 0.3

[[events]]
kind = "kidnap"
time = 12.0
offset = [1.0, -0.5, 0.3]
"""


def live_run(scenario_file: Path, out: Path, ticks: int = 200, seed: int = 11,
             filters=("ekf", "dead_reckoning"), close: bool = True):
    """Play a session the way the window does: keyboard-like controls, user commands,
    recorder called before each step. Returns the live steps, runner and recorder."""
    sc = load_scenario(scenario_file)
    sim = Simulation(sc, seed)
    built = {f: build_filter(f, sc, seed, name=f) for f in filters}
    runner = FilterRunner(built)
    rec = Recorder(out, sc, seed, list(filters), {})
    rec.attach(runner)  # the filters' settings and estimate digests go into the file
    rng = np.random.default_rng(5)  # the "user" at the keyboard
    commands = {40: [{"kind": "kidnap", "pose": [3.0, 7.0, -2.5]}], 90: [{"kind": "reset"}],
                130: [{"kind": "kidnap"}], 150: [{"kind": "toggle", "filter": "ekf"}]}
    steps = []
    for tick in range(1, ticks + 1):
        control = Control(float(rng.uniform(-0.2, 0.8)), float(rng.uniform(-1, 1)))
        cmds = commands.get(tick, [])
        rec.record_tick(tick, control, cmds)
        apply_commands(cmds, sim, built, sc)
        step = sim.step(control)
        runner.feed(step)
        steps.append(step)
    if close:
        rec.close()
    return steps, runner, rec, sim

