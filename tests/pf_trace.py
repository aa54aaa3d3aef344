"""A particle filter's whole output over scripted ticks, as one SHA-256 (tests/filters/test_particle_bits.py).

Each case runs a ParticleFilter through 60 ticks of a scripted tour with the readings of
several sensor kinds (bearings with declared outliers, range-bearings, pose and position
fixes, empty ticks), and hashes every estimate, the particles, the weights and the HUD
figures after each tick: any change in a result or in the order of the random draws changes
the hash.
"""

from __future__ import annotations

import hashlib

import numpy as np

from beacon_sim.core.measurement_models import bearing, range_bearing
from beacon_sim.core.motion import MotionNoise, move
from beacon_sim.core.sensors import SensorNoise, SensorSpec
from beacon_sim.core.types import Beacon, Control, Measurement
from beacon_sim.core.world import World
from beacon_sim.filters.base import FilterContext, GaussianBelief
from beacon_sim.filters.particle.pf import ParticleFilter

WORLD = World((0.0, 0.0, 10.0, 10.0), tuple(Beacon(i + 1, x, y) for i, (x, y) in enumerate(
    [(1.0, 1.0), (9.0, 1.5), (8.5, 9.0), (1.5, 8.0), (5.0, 5.5)])))
SENSORS = (
    SensorSpec("b", "bearing", noise=SensorNoise(bearing_std=0.05), outlier_rate=0.1),
    SensorSpec("rb", "range_bearing", noise=SensorNoise(range_std=0.1, bearing_std=0.05)),
    SensorSpec("pose", "pose", noise=SensorNoise(position_std=0.1, heading_std=0.05)),
    SensorSpec("gps", "position", noise=SensorNoise(position_std=0.2)),
    SensorSpec("b0", "bearing", noise=SensorNoise(bearing_std=0.08)),
)
NOISES = {"plain": MotionNoise(v_std=0.02, v_frac=0.05, omega_std=0.03, omega_frac=0.05),
          "pose_std": MotionNoise(v_std=0.02, v_frac=0.05, omega_std=0.03, omega_frac=0.05,
                                  pose_std=(0.01, 0.0, 0.005))}

CASES = {
    "default": {},
    "float64": {"dtype": "float64"},
    "kld": {"adaptive": "kld", "n_min": 100, "n_max": 900},
    "seed002": {"adaptive": "seed002", "n_min": 100, "n_max": 900, "ver_max": 50.0},
    "temper": {"temper_ess": 0.3},
    "cluster_heading": {"estimate": "cluster", "heading_weight": True, "roughen": 0.5},
    "mean_fit": {"recovery_fit": "mean", "resampler": "stratified"},
    "residual": {"resampler": "residual", "augmented": False},
    "multinomial": {"resampler": "multinomial", "lost_cov": False},
}


def ticks(n: int = 60, seed: int = 3) -> list[tuple[Control, list[Measurement]]]:
    """The scripted tour: commands and each tick's readings (noisy, a few outliers, a
    kidnap-like jump of the readings at tick 40)."""
    rng = np.random.default_rng(seed)
    pose = np.array([3.0, 3.0, 0.2])
    out = []
    for t in range(n):
        u = Control(0.5 + 0.2 * np.sin(t / 7.0), 0.3 * np.cos(t / 5.0))
        pose = move(pose, u.v, u.omega, 0.1)
        seen = pose + (np.array([2.5, -1.0, 1.0]) if t >= 40 else 0.0)
        ms: list[Measurement] = []
        if t % 5 != 4:
            ids = np.array([1, 2, 3, 4, 5])[rng.random(5) < 0.7]
            xy = WORLD.beacon_positions(ids)
            z = bearing(seen, xy) + rng.normal(0, 0.05, len(ids))
            z[rng.random(len(ids)) < 0.1] += 2.0
            ms.append(Measurement("b", "bearing", z[:, None], ids))
        if t % 4 == 1:
            ids = np.array([4, 1, 3])
            z = bearing(seen, WORLD.beacon_positions(ids)) + rng.normal(0, 0.08, 3)
            ms.append(Measurement("b0", "bearing", z[:, None], ids))
        if t % 3 == 0:
            ids = np.array([2, 5])
            z = range_bearing(seen, WORLD.beacon_positions(ids)) + rng.normal(0, [0.1, 0.05], (2, 2))
            ms.append(Measurement("rb", "range_bearing", z, ids))
        if t % 11 == 7:
            ms.append(Measurement("pose", "pose", (seen + rng.normal(0, 0.05, 3))[None], np.arange(3)))
        if t % 13 == 5:
            ms.append(Measurement("gps", "position", (seen[:2] + rng.normal(0, 0.2, 2))[None],
                                  np.array([1, 2, 3, 4]), hdop=1.4))
        out.append((u, ms))
    return out


def trace(case: str, noise: str = "plain", n: int = 600, start: str = "gaussian") -> str:
    """The SHA-256 of everything the filter reports over :func:`ticks`."""
    ctx = FilterContext("pf", WORLD, 0.1, NOISES[noise], SENSORS, {"n_particles": n, **CASES[case]},
                        np.random.default_rng(11))
    pf = ParticleFilter(ctx)
    pf.reset(GaussianBelief(np.array([3.0, 3.0, 0.2]), np.diag([0.04, 0.04, 0.01]))
             if start == "gaussian" else None)
    h = hashlib.sha256()
    for u, ms in ticks():
        pf.predict(u, 0.1)
        pf.update(ms)
        mean, cov = pf.estimate()
        b = pf.belief()
        for a in (mean, cov, np.ascontiguousarray(b.poses), b.weights):
            h.update(np.ascontiguousarray(a).tobytes())
        h.update(repr((pf.n, pf.w_slow, pf.w_fast, pf.inject_prob, pf.lost, pf.ess)).encode())
    return h.hexdigest()


RUNS = [(c, "plain", "gaussian") for c in CASES] + [("default", "pose_std", "gaussian"),
                                                     ("default", "plain", "uniform"),
                                                     ("kld", "pose_std", "uniform")]

if __name__ == "__main__":
    for c, noise, start in RUNS:
        print(f'    ("{c}", "{noise}", "{start}"): "{trace(c, noise, start=start)}",')
