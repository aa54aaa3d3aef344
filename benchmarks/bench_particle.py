"""Step time of the vectorised particle filter against a per-particle Python loop, and of
the histogram filter on its default grid.

Run:  .venv/bin/python benchmarks/bench_particle.py [--quick]

The loop is written the way common teaching code does it (PythonRobotics' particle filter
localization: a column vector per particle, matrix motion model, a Python loop over the
beacons, a weight product, then a loop-based low-variance resampling).
Targets (2-core VM): >= 50x the loop at 1k particles; <= 15 ms/step at 100k; <= 10 ms/step
for a 90,000-cell grid.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from figures import figure

from beacon_sim.core.measurement_models import bearing
from beacon_sim.core.motion import MotionNoise, move
from beacon_sim.core.sensors import SensorNoise, SensorSpec
from beacon_sim.core.types import Beacon, Control, Measurement
from beacon_sim.core.world import World
from beacon_sim.filters.base import FilterContext, GaussianBelief
from beacon_sim.filters.grid.histogram import HistogramFilter
from beacon_sim.filters.particle.pf import ParticleFilter

WORLD = World((0.0, 0.0, 10.0, 10.0),
              tuple(Beacon(i + 1, x, y) for i, (x, y) in enumerate([(1, 1), (9, 1), (9, 9), (1, 9)])))
SPEC = SensorSpec("b", "bearing", noise=SensorNoise(bearing_std=0.05))
NOISE = MotionNoise(v_std=0.02, v_frac=0.05, omega_std=0.03, omega_frac=0.05)
DT = 0.1
U = Control(0.4, 0.1)


def steps(n):
    """True poses and the 4 bearings seen from each (noise-free: the cost does not care)."""
    pose = np.array([5.0, 5.0, 0.0])
    out = []
    for _ in range(n):
        pose = move(pose, U.v, U.omega, DT)
        z = bearing(pose, WORLD.beacon_xy)[:, None]
        out.append(Measurement("b", "bearing", z, WORLD.beacon_ids.copy()))
    return out


def time_filter(flt, meas, reps):
    for m in meas[:3]:
        flt.predict(U, DT)
        flt.update([m])
        flt.estimate()
    t0 = time.perf_counter()
    for m in meas[3: 3 + reps]:
        flt.predict(U, DT)
        flt.update([m])
        flt.estimate()
    return (time.perf_counter() - t0) / reps * 1e3


# --------------------------------------------------------------------- the teaching loop
def loop_pf_step(px, pw, z_rows, rng):
    """One step of a per-particle particle filter, PythonRobotics style. px (3, N), pw (1, N)."""
    n = px.shape[1]
    for ip in range(n):
        x = np.array([px[:, ip]]).T
        w = pw[0, ip]
        sv, sw = NOISE.control_std(U.v, U.omega)
        ud = np.array([[U.v + rng.standard_normal() * sv, U.omega + rng.standard_normal() * sw]]).T
        F = np.eye(3)
        B = np.array([[DT * math.cos(x[2, 0]), 0], [DT * math.sin(x[2, 0]), 0], [0.0, DT]])
        x = F @ x + B @ ud
        for i in range(z_rows.shape[0]):
            bx, by = WORLD.beacon_xy[i]
            pre = math.atan2(by - x[1, 0], bx - x[0, 0]) - x[2, 0]
            dz = (z_rows[i, 0] - pre + math.pi) % (2 * math.pi) - math.pi
            w *= math.exp(-dz**2 / (2 * 0.05**2)) / math.sqrt(2 * math.pi * 0.05**2)
        px[:, ip] = x[:, 0]
        pw[0, ip] = w
    pw = pw / pw.sum()
    x_est = px.dot(pw.T)
    d = px - x_est
    p_est = (d * pw) @ d.T
    n_eff = 1.0 / (pw.dot(pw.T))[0, 0]
    if n_eff < n / 2:
        w_cum = np.cumsum(pw)
        base = np.arange(0.0, 1.0, 1 / n)
        re_ids = base + rng.random() / n
        idx = []
        ind = 0
        for ip in range(n):
            while re_ids[ip] > w_cum[ind]:
                ind += 1
            idx.append(ind)
        px = px[:, idx]
        pw = np.zeros((1, n)) + 1.0 / n
    return px, pw, x_est, p_est


def time_loop(n, meas, reps, rng):
    px = np.array([5.0, 5.0, 0.0])[:, None] + rng.normal(0, 0.1, (3, n))
    pw = np.full((1, n), 1.0 / n)
    px, pw, *_ = loop_pf_step(px, pw, meas[0].z, rng)
    t0 = time.perf_counter()
    for m in meas[1: 1 + reps]:
        px, pw, *_ = loop_pf_step(px, pw, m.z, rng)
    return (time.perf_counter() - t0) / reps * 1e3


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer repetitions, no 1M")
    args = ap.parse_args(argv)
    meas = steps(60)
    rng = np.random.default_rng(0)
    sizes = [1_000, 10_000, 100_000] + ([] if args.quick else [1_000_000])
    print(f"{'N':>9} {'vectorised ms/step':>19} {'loop ms/step':>13} {'ratio':>7}")
    for n in sizes:
        ctx = FilterContext("pf", WORLD, DT, NOISE, (SPEC,), {"n_particles": n},
                            np.random.default_rng(1))
        pf = ParticleFilter(ctx)
        pf.reset(GaussianBelief(np.array([5.0, 5.0, 0.0]), np.diag([0.01, 0.01, 0.01])))
        reps = 5 if n >= 1_000_000 else (20 if args.quick else 40)
        vec = time_filter(pf, meas, reps)
        if n <= 10_000:
            loop = time_loop(n, meas, 3 if n > 1000 else 10, rng)
            print(f"{n:>9} {vec:>19.3f} {loop:>13.1f} {loop / vec:>6.0f}x")
            figure(f"pf step, {n:,} particles", vec, "ms", peer="per-particle loop",
                   peer_value=loop, target=1 / 50 if n == 1000 else None, target_of="ratio")
        else:
            print(f"{n:>9} {vec:>19.3f} {'-':>13} {'-':>7}")
            figure(f"pf step, {n:,} particles", vec, "ms", target=15.0 if n == 100_000 else None)
    ctx = FilterContext("histogram", WORLD, DT, NOISE, (SPEC,), {}, np.random.default_rng(1))
    hf = HistogramFilter(ctx)
    ms = time_filter(hf, meas, 20 if args.quick else 50)
    print(f"histogram {hf.grid.shape} = {hf.grid.size} cells: {ms:.3f} ms/step "
          "(predict + update with 4 bearings + estimate)")
    figure(f"histogram step, {hf.grid.size:,} cells", ms, "ms", target=10.0)


if __name__ == "__main__":
    main()
