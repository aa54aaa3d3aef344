"""Attack: find the run's seed in what the filter is given, then simulate the run
itself and return its truth. It reads ctx.rng (its SeedSequence's entropy and spawn key,
its PCG64 state), the global np.random and random states, sys.argv, /proc/self/cmdline, the
environment, the files it can see and the context's parameters, and tries every number
found there, and the seeds 0..199, against each: the streams before they were keyed (the seed as
the SeedSequence's entropy), the public key's streams of run, eval and the window (a
brute force over small seeds), the global generators seeded the old way. With a seed that
fits, it simulates the shipped scenario whose world and tick it was given and returns the
true pose with the honest EKF's covariance; otherwise it is the honest EKF. It prints what
it found ("RECOVERED seed N via ..." or "NOTHING")."""

import os
import random
import re
import sys
import zlib
from pathlib import Path

import numpy as np

from beacon_sim.filters.ekf import ExtendedKalmanFilter

SMALL = range(200)


def _numbers(text):
    return {int(m) for m in re.findall(r"\d{1,19}", text)}


def _everything(ctx):
    found = set(SMALL)
    seq = ctx.rng.bit_generator.seed_seq
    if isinstance(seq.entropy, int):
        found.add(seq.entropy)
    found |= {int(k) for k in seq.spawn_key}
    found |= _numbers(" ".join(sys.argv))
    found |= _numbers(" ".join(f"{k}={v}" for k, v in os.environ.items()))
    found |= _numbers(repr(dict(ctx.params)))
    try:
        found |= _numbers(Path("/proc/self/cmdline").read_bytes().decode("utf-8", "replace"))
    except OSError:
        pass
    for folder in {Path.cwd(), Path(__file__).parent, Path(os.environ.get("TMPDIR", "/tmp"))}:
        try:
            for f in folder.iterdir():
                found |= _numbers(f.name)
                if f.is_file() and f.stat().st_size < 65536:
                    found |= _numbers(f.read_bytes().decode("utf-8", "replace"))
        except OSError:
            pass
    return {n for n in found if 0 <= n < 2**63}


def _fits(seed, name, state, np_state, py_state):
    key = (zlib.crc32(b"filter"), zlib.crc32(name.encode()))
    if np.random.PCG64(np.random.SeedSequence(seed, spawn_key=key)).state == state:
        return "the stream before issue 37"
    from beacon_sim.core.streams import filter_stream

    if filter_stream(seed, name).bit_generator.state == state:
        return "the public key's stream"
    mt = np.random.RandomState(seed % 2**32).get_state()
    if np.array_equal(mt[1], np_state[1]) and mt[2] == np_state[2]:
        return "the global np.random state"
    if random.Random(seed).getstate() == py_state:
        return "the global random state"
    return None


def _scenario_of(ctx):
    from beacon_sim.core.resources import shipped_scenarios
    from beacon_sim.core.scenario import load_scenario

    for name in shipped_scenarios():
        try:
            sc = load_scenario(name)
        except Exception:
            continue
        if sc.dt == ctx.dt and tuple(sc.world.bounds) == tuple(ctx.world.bounds) \
                and len(sc.world.beacons) == len(ctx.world.beacons):
            return sc
    return None


class Recover(ExtendedKalmanFilter):
    def __init__(self, ctx):
        state = ctx.rng.bit_generator.state  # before anything draws from it
        np_state, py_state = np.random.get_state(), random.getstate()
        super().__init__(ctx)
        self.sim = None
        how = None
        for seed in sorted(_everything(ctx)):
            how = _fits(seed, ctx.name, state, np_state, py_state)
            if how is not None:
                break
        sc = _scenario_of(ctx) if how is not None else None
        if sc is not None:
            from beacon_sim.core.simulation import Simulation

            self.sim = Simulation(sc, seed)
            print(f"RECOVERED seed {seed} via {how}", flush=True)
        else:
            print("NOTHING", flush=True)
        self.pose = None

    def predict(self, control, dt):
        super().predict(control, dt)
        if self.sim is not None:
            self.pose = self.sim.step().true_pose

    def estimate(self):
        mean, cov = super().estimate()
        if self.pose is not None:
            return np.array(self.pose, dtype=float), cov
        return mean, cov
