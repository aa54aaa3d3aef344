"""The performance goals, each as a ratio against a peer measured in the same run, CPU beside wall.

Run:  python benchmarks/bench_goals.py [--quick]

Rows (targets in brackets; docs/performance.md keeps the table):
- pf step at 100k particles / a minimal hand-written numpy particle filter (<= 1.2x);
- pf step / the tight numpy floor (``TightPF``: our models, every buffer kept) at 1k
  (<= 1.3x) and 100k (<= 1.15x) particles, the median of interleaved rounds;
- ekf step / a plain-Python sequential EKF, 4 bearings a step (<= 1.2x);
- ukf step / ekf step on the same problem (<= 2.5x);
- the runner's guard of one estimate (<= 3 us), beside an EKF step;
- headless `default`, 120 s, all six filters: CPU (<= 2.0 s), beside the bare simulation;
- ukf step and a batched eval with 1000 beacons in view / 100 in view (<= 15x: linear);
  the ekf step with 1000 in view / the ukf's (<= 1.0; all counts: bench_readings.py);
- a batched eval on a 1000-beacon map with 2 in view / the per-run path (sizing by readings).
The eval (100 x 2,000 x 3 filters, 2 jobs) and the window's frame are bench_eval.py and
bench_frame.py. Everything runs with numpy's BLAS on one thread (``figures.py``).
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import time
import tomllib

import numpy as np
from bench_particle import DT, NOISE, SPEC, WORLD, U, steps
from figures import Clock, figure

from beacon_sim.core.resources import scenario_dir
from beacon_sim.core.scenario import load_scenario, parse_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.evaluation.montecarlo import run_monte_carlo
from beacon_sim.filters.base import FilterContext, GaussianBelief
from beacon_sim.filters.particle.pf import ParticleFilter
from beacon_sim.hosting.loading import build_filter
from beacon_sim.hosting.runner import validate_estimate
from beacon_sim.runs.headless import run_headless

TWO_PI = 2.0 * math.pi


# ------------------------------------------------------------- a minimal numpy particle filter
def minimal_pf_step(p, w, z, rng, sigma=0.05):
    """Sample the motion, weight by the 4 bearings, estimate, resample when ESS < N / 2.
    p (N, 3), w (N,); returns (p, w, mean, cov)."""
    n = len(w)
    sv, sw = NOISE.control_std(U.v, U.omega)
    v = U.v + sv * rng.standard_normal(n)
    om = U.omega + sw * rng.standard_normal(n)
    th = p[:, 2]
    p[:, 0] += v * DT * np.cos(th)
    p[:, 1] += v * DT * np.sin(th)
    p[:, 2] = (th + om * DT + math.pi) % TWO_PI - math.pi
    logw = np.log(w)
    for (bx, by), zj in zip(WORLD.beacon_xy, z[:, 0], strict=True):
        d = (zj - np.arctan2(by - p[:, 1], bx - p[:, 0]) + p[:, 2] + math.pi) % TWO_PI - math.pi
        logw -= 0.5 * (d / sigma) ** 2
    w = np.exp(logw - logw.max())
    w /= w.sum()
    mean = np.array([w @ p[:, 0], w @ p[:, 1],
                     math.atan2(w @ np.sin(p[:, 2]), w @ np.cos(p[:, 2]))])
    d = p - mean
    d[:, 2] = (d[:, 2] + math.pi) % TWO_PI - math.pi
    cov = (d * w[:, None]).T @ d
    if 1.0 / (w @ w) < n / 2:
        idx = np.searchsorted(np.cumsum(w), (rng.random() + np.arange(n)) / n)
        p = p[np.minimum(idx, n - 1)]
        w = np.full(n, 1.0 / n)
    return p, w, mean, cov


class TightPF:
    """The floor a hand-vectorised numpy particle filter with our PF's models reaches: float32
    rows x, y, theta, every buffer allocated once, the same motion (two normal draws a
    particle, walls clip), the same von Mises bearing likelihood (the cos-innovation form,
    no arctan), log-weights normalised, the weighted mean and covariance, systematic
    resampling when ESS < N / 2, and nothing else (no lost test, recovery, collapse floor or
    validation)."""

    def __init__(self, n, rng, kappa=1.0 / 0.05 ** 2):
        self.n, self.rng, self.kappa = n, rng, kappa
        f32 = np.float32
        self.P = (np.array([5.0, 5.0, 0.0])[:, None] + rng.normal(0, 0.1, (3, n))).astype(f32)
        self.P2 = np.empty_like(self.P)
        self.logw = np.full(n, -math.log(n))
        self.w = np.full(n, 1.0 / n)
        self.a, self.b, self.c, self.s = (np.empty(n, f32) for _ in range(4))
        k = len(WORLD.beacons)
        self.T1, self.T2, self.T3, self.DX, self.DY = (np.empty((k, n), f32) for _ in range(5))
        self.bx = WORLD.beacon_xy[:, 0:1].astype(f32)
        self.by = WORLD.beacon_xy[:, 1:2].astype(f32)
        self.E = np.empty((3, n), f32)
        self.ll = np.empty(n)
        self.sv, self.sw = (float(x) for x in NOISE.control_std(U.v, U.omega))
        self.bounds = WORLD.bounds

    def step(self, z):
        n, rng, P = self.n, self.rng, self.P
        x, y, th = P[0], P[1], P[2]
        v, w, c, s = self.a, self.b, self.c, self.s
        rng.standard_normal(n, dtype=np.float32, out=v)
        rng.standard_normal(n, dtype=np.float32, out=w)
        v *= self.sv * DT
        v += U.v * DT
        w *= self.sw * DT
        w += U.omega * DT
        np.cos(th, out=c)
        np.sin(th, out=s)
        c *= v
        s *= v
        x += c
        y += s
        th += w
        np.add(th, math.pi, out=w)
        w *= 1.0 / TWO_PI
        np.floor(w, out=w)
        w *= TWO_PI
        th -= w
        xmin, ymin, xmax, ymax = self.bounds
        np.clip(x, xmin, xmax, out=x)
        np.clip(y, ymin, ymax, out=y)
        # von Mises bearings: kappa (cos(z - h) - 1), cos(z - h) from dx, dy, cos, sin
        T1, T2, T3, DX, DY = self.T1, self.T2, self.T3, self.DX, self.DY
        np.cos(th, out=c)
        np.sin(th, out=s)
        cz = np.cos(z[:, -1]).astype(np.float32)[:, None]
        sz = np.sin(z[:, -1]).astype(np.float32)[:, None]
        np.subtract(self.bx, x, out=DX)
        np.subtract(self.by, y, out=DY)
        np.multiply(c, cz, out=T1)
        np.multiply(s, sz, out=T2)
        T1 -= T2
        T1 *= DX
        np.multiply(s, cz, out=T2)
        np.multiply(c, sz, out=T3)
        T2 += T3
        T2 *= DY
        T1 += T2
        np.multiply(DX, DX, out=T2)
        np.multiply(DY, DY, out=T3)
        T2 += T3
        np.sqrt(T2, out=T2)
        np.maximum(T2, 1e-6, out=T2)
        T1 /= T2
        T1 -= 1.0
        T1 *= self.kappa
        logw, wn = self.logw, self.w
        logw += T1.sum(axis=0, dtype=np.float64)
        logw -= logw.max()                    # log-weights relative to the best
        np.exp(logw, out=wn)
        wn *= 1.0 / wn.sum()
        # estimate
        E, wt = self.E, self.a
        wt[:] = wn
        mx, my = float(np.dot(wt, x)), float(np.dot(wt, y))
        mth = math.atan2(float(np.dot(wt, s)), float(np.dot(wt, c)))
        np.subtract(x, mx, out=E[0])
        np.subtract(y, my, out=E[1])
        e = E[2]
        np.subtract(th, mth, out=e)
        if np.logical_or.reduce(e >= math.pi):
            e[e >= math.pi] -= TWO_PI
        if np.logical_or.reduce(e < -math.pi):
            e[e < -math.pi] += TWO_PI
        cov = ((E * wt) @ E.T).astype(np.float64)
        mean = np.array([mx, my, mth])
        # systematic resampling
        if 1.0 / float(np.dot(wn, wn)) < 0.5 * n:
            cum = np.cumsum(wn)
            cum *= n / cum[-1]
            idx = np.searchsorted(cum, rng.random() + np.arange(n))
            np.minimum(idx, n - 1, out=idx)
            for row in range(3):
                np.take(P[row], idx, out=self.P2[row])
            self.P, self.P2 = self.P2, self.P
            logw.fill(0.0)
            wn.fill(1.0 / n)
        return mean, cov


def pf_rows(n, reps, floor="minimal", tries=2):
    """Our PF's step (predict, update, estimate) against a floor (``minimal``:
    :func:`minimal_pf_step`; ``tight``: :class:`TightPF`) on the same ``reps`` ticks,
    interleaved: each round starts both from the same belief (a tracked start near the
    truth) and times ours, then the floor. Returns (our best round, the floor's best round,
    the median over the rounds of the ratio ours / floor), process CPU time in the clocks."""
    meas = steps(reps + 3)
    ctx = FilterContext("pf", WORLD, DT, NOISE, (SPEC,), {"n_particles": n}, np.random.default_rng(1))
    pf = ParticleFilter(ctx)
    start = GaussianBelief(np.array([5.0, 5.0, 0.0]), np.diag([0.01, 0.01, 0.01]))
    rng = np.random.default_rng(2)
    ours = mine = None
    ratios = []
    for i in range(tries + 1):   # the first round warms up and is not counted
        pf.reset(start)
        p = np.array([5.0, 5.0, 0.0]) + rng.normal(0, 0.1, (n, 3))
        w = np.full(n, 1.0 / n)
        tight = TightPF(n, rng)
        with Clock() as a:
            for m in meas[:reps]:
                pf.predict(U, DT)
                pf.update([m])
                pf.estimate()
        with Clock() as b:
            if floor == "tight":
                for m in meas[:reps]:
                    tight.step(m.z)
            else:
                for m in meas[:reps]:
                    p, w, *_ = minimal_pf_step(p, w, m.z, rng)
        if i == 0:
            continue
        ratios.append(a.cpu / b.cpu)
        ours = a if ours is None or a.cpu < ours.cpu else ours
        mine = b if mine is None or b.cpu < mine.cpu else mine
    return ours, mine, statistics.median(ratios)


# ------------------------------------------------------------- a plain-Python sequential EKF
class PlainEKF:
    """[x, y, theta] on floats, P as its six entries; bearings one at a time (scalar S)."""

    def __init__(self, sc, mean, cov):
        self.noise, self.std = sc.motion_noise, sc.sensors[0].noise.bearing_std
        self.xy = {b.id: (b.x, b.y) for b in sc.world.beacons}
        self.x, self.y, self.th = (float(v) for v in mean)
        c = np.asarray(cov)
        self.p = [c[0, 0], c[0, 1], c[0, 2], c[1, 1], c[1, 2], c[2, 2]]

    def predict(self, u, dt):
        v, w, th = u.v, u.omega, self.th
        c, s = math.cos(th), math.sin(th)
        n = self.noise
        sv = n.v_std + n.v_frac * abs(v)
        sw = n.omega_std + n.omega_frac * abs(w)
        qv, ps = dt * dt * sv * sv, n.pose_std
        a, b = -v * dt * s, v * dt * c
        p00, p01, p02, p11, p12, p22 = self.p
        self.p = [p00 + 2 * a * p02 + a * a * p22 + qv * c * c + ps[0] ** 2,
                  p01 + a * p12 + b * p02 + a * b * p22 + qv * c * s,
                  p02 + a * p22,
                  p11 + 2 * b * p12 + b * b * p22 + qv * s * s + ps[1] ** 2,
                  p12 + b * p22,
                  p22 + dt * dt * sw * sw + ps[2] ** 2]
        self.x += v * dt * c
        self.y += v * dt * s
        self.th = (th + w * dt + math.pi) % TWO_PI - math.pi

    def update(self, measurements):
        r = self.std * self.std
        for m in measurements:
            for zr, bid in zip(m.z.tolist(), m.beacon_ids.tolist(), strict=True):
                bx, by = self.xy[bid]
                dx, dy = bx - self.x, by - self.y
                q = dx * dx + dy * dy
                h0, h1 = dy / q, -dx / q           # H = [h0, h1, -1]
                p00, p01, p02, p11, p12, p22 = self.p
                ph0 = p00 * h0 + p01 * h1 - p02    # P H^T
                ph1 = p01 * h0 + p11 * h1 - p12
                ph2 = p02 * h0 + p12 * h1 - p22
                s = h0 * ph0 + h1 * ph1 - ph2 + r
                k0, k1, k2 = ph0 / s, ph1 / s, ph2 / s
                nu = (zr[-1] - (math.atan2(dy, dx) - self.th) + math.pi) % TWO_PI - math.pi
                self.x += k0 * nu
                self.y += k1 * nu
                self.th = (self.th + k2 * nu + math.pi) % TWO_PI - math.pi
                self.p = [p00 - k0 * ph0, p01 - k0 * ph1, p02 - k0 * ph2,
                          p11 - k1 * ph1, p12 - k1 * ph2, p22 - k2 * ph2]


def krejsa(kind, n_steps):
    data = tomllib.loads((scenario_dir() / "krejsa_bearing_only.toml").read_text())
    data["duration"] = n_steps * data["dt"]
    data["events"] = []
    s = data["sensors"][0]
    s["detection_prob"] = 1.0
    if kind == "range_bearing":
        s["kind"], s["range_std"] = "range_bearing", 0.1
    sc = parse_scenario(data, "bench", name=f"krejsa_{kind}")
    return sc, Simulation(sc, 0).run(sc.duration)


def time_steps(f, stp, repeat=3):
    """Best CPU (and its wall) per step of predict + update over ``stp`` [us]."""
    best = None
    for _ in range(repeat):
        f.reset(None) if hasattr(f, "reset") else None
        with Clock() as c:
            for st in stp:
                f.predict(st.control, st.dt)
                f.update(st.measurements)
        best = c if best is None or c.cpu < best.cpu else best
    return best.wall / len(stp) * 1e6, best.cpu / len(stp) * 1e6


# ------------------------------------------------------------- many beacons
def beacon_scenario(n_beacons, in_view, seed=0):
    """`default`'s room and tour with ``n_beacons`` beacons; ``in_view`` of them in the room and
    seen (range-bearing, no range limit within the map, always detected), the rest far away."""
    data = tomllib.loads((scenario_dir() / "default.toml").read_text())
    rng = np.random.default_rng(seed)
    far = n_beacons - in_view
    xs = list(rng.uniform(0.5, 11.5, in_view)) + list(rng.uniform(1000.0, 2000.0, far))
    ys = list(rng.uniform(0.5, 7.5, in_view)) + list(rng.uniform(0.5, 7.5, far))
    data["world"]["bounds"] = [0.0, 0.0, 2000.0, 8.0] if far else [0.0, 0.0, 12.0, 8.0]
    data["world"]["beacons"] = [{"id": i + 1, "x": float(x), "y": float(y)}
                                for i, (x, y) in enumerate(zip(xs, ys, strict=True))]
    s = data["sensors"][0]
    s["max_range"], s["detection_prob"], s["period"] = 50.0, 1.0, data["dt"]
    data["events"] = []
    return parse_scenario(data, "bench", name=f"beacons_{n_beacons}_{in_view}")


def eval_time(sc, specs, runs, duration, batch, tries=1):
    """The least disturbed (least CPU) of ``tries`` evaluations in this process."""
    best = None
    for _ in range(tries):
        with Clock() as c:
            run_monte_carlo(sc, specs, runs, seed=0, duration=duration, jobs=1, progress=False, batch=batch)
        if best is None or c.cpu < best.cpu:
            best = c
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer steps")
    args = ap.parse_args()
    q = args.quick
    print(f"load average at start: {os.getloadavg()[0]:.2f}; figures: wall (CPU)")

    # PF at 100k particles against the minimal numpy PF
    ours, mine, _ = pf_rows(100_000, 10 if q else 30)
    n = 10 if q else 30
    print(f"pf 100k: ours {ours.wall / n * 1e3:.2f} ({ours.cpu / n * 1e3:.2f}) ms/step, minimal numpy "
          f"{mine.wall / n * 1e3:.2f} ({mine.cpu / n * 1e3:.2f}) ms/step")
    figure("pf step, 100k particles (CPU)", ours.cpu / n * 1e3, "ms", peer="minimal numpy pf",
           peer_value=mine.cpu / n * 1e3, target=1.2, target_of="ratio")

    # PF against the tight floor: fixed per-call costs at 1k, the whole at 100k
    # many short interleaved rounds (a 1k round is ~20 ms): the median is decisive at load
    floors = ((1_000, 100, 15 if q else 31, 1.3), (100_000, 10 if q else 20, 7 if q else 9, 1.15))
    for count, reps, tries, target in floors:
        a, b, ratio = pf_rows(count, reps, "tight", tries=tries)
        print(f"pf {count:,}: ours {a.cpu / reps * 1e6:.0f} us CPU/step, tight numpy floor "
              f"{b.cpu / reps * 1e6:.0f} us; median ratio of {tries} interleaved rounds {ratio:.2f}x")
        figure(f"pf step, {count:,} particles / tight numpy floor (CPU, median of rounds)", ratio, "x",
               target=target)

    # EKF against a plain-Python sequential EKF; UKF against the EKF
    sc, stp = krejsa("bearing", 300 if q else 1000)
    ekf, ukf = build_filter("ekf", sc, 0), build_filter("ukf", sc, 0)
    ekf.reset(None)
    b0 = ekf.estimate()
    plain = PlainEKF(sc, *b0)

    def plain_reset(_=None):
        plain.__init__(sc, *b0)
    plain.reset = plain_reset
    e_w, e_c = time_steps(ekf, stp)
    p_w, p_c = time_steps(plain, stp)
    u_w, u_c = time_steps(ukf, stp)
    print(f"4 bearings a step: ekf {e_w:.1f} ({e_c:.1f}) us, plain-Python ekf {p_w:.1f} ({p_c:.1f}) us, "
          f"ukf {u_w:.1f} ({u_c:.1f}) us")
    figure("ekf step, 4 bearings (CPU)", e_c, "us", peer="plain-Python sequential ekf", peer_value=p_c,
           target=1.2, target_of="ratio")
    figure("ukf step, 4 bearings (CPU)", u_c, "us", peer="our ekf", peer_value=e_c, target=2.5,
           target_of="ratio")
    sc_rb, stp_rb = krejsa("range_bearing", 300 if q else 1000)
    e2 = time_steps(build_filter("ekf", sc_rb, 0), stp_rb)[1]
    u2 = time_steps(build_filter("ukf", sc_rb, 0), stp_rb)[1]
    figure("ukf step, 4 range-bearings (CPU)", u2, "us", peer="our ekf", peer_value=e2, target=2.5,
           target_of="ratio")

    # The runner's guard
    est = ekf.estimate()
    k = 20_000
    with Clock() as g:
        for _ in range(k):
            validate_estimate(est)
    print(f"guard: {g.wall / k * 1e6:.2f} ({g.cpu / k * 1e6:.2f}) us per estimate")
    figure("runner guard, one estimate (CPU)", g.cpu / k * 1e6, "us", peer="ekf step", peer_value=e_c,
           target=3.0)

    # Headless default, 120 s, all six filters
    dsc = load_scenario("default")
    six = ["kf", "ekf", "ukf", "pf", "histogram", "dead_reckoning"]
    with Clock() as bare:
        Simulation(dsc, 0).run(120.0)
    with Clock() as h:
        res = run_headless(dsc, six, seed=0, duration=120.0)
    print(f"headless default 120 s, six filters: {h.wall:.2f} s wall, {h.cpu:.2f} s CPU (bare simulation "
          f"{bare.cpu:.2f} s CPU); per step: " + ", ".join(
              f"{nm} {t.us_per_step:.0f} us" for nm, t in res.runner.tracks.items()))
    figure("headless default 120 s, six filters, CPU", h.cpu, "s", peer="bare simulation",
           peer_value=bare.cpu, target=2.0)

    # Linear in the readings: 1000 beacons in view against 100
    per = {}
    for nb in (100, 1000):
        bsc = beacon_scenario(nb, nb)
        bst = Simulation(bsc, 0).run(0.5 if q else 1.0)
        per[nb] = {f: time_steps(build_filter(f, bsc, 0), bst, repeat=1)[1] for f in ("ekf", "ukf")}
        per[nb]["eval"] = eval_time(bsc, ["ekf", "ukf"], 4, 0.5 if q else 1.0, True, tries=2).cpu
        print(f"{nb} beacons in view: ekf {per[nb]['ekf']:.0f} us, ukf {per[nb]['ukf']:.0f} us CPU a step; "
              f"batched eval (4 runs) {per[nb]['eval']:.2f} s CPU")
    figure("ekf step, 1000 beacons in view (CPU)", per[1000]["ekf"], "us", peer="our ukf",
           peer_value=per[1000]["ukf"], target=1.0, target_of="ratio")
    figure("ukf step, 1000 beacons in view (CPU)", per[1000]["ukf"], "us", peer="100 in view",
           peer_value=per[100]["ukf"], target=15.0, target_of="ratio")
    figure("batched eval ekf+ukf, 1000 in view (CPU)", per[1000]["eval"], "s", peer="100 in view",
           peer_value=per[100]["eval"], target=15.0, target_of="ratio")

    # Sized by the readings: a 1000-beacon map with 2 in view, batched against per-run
    bsc = beacon_scenario(1000, 2)
    dur = 1.0 if q else 3.0
    bt = eval_time(bsc, ["ekf", "ukf"], 4, dur, True, tries=3)
    pr = eval_time(bsc, ["ekf", "ukf"], 4, dur, False, tries=3)
    print(f"1000-beacon map, 2 in view, 4 runs x {dur:g} s: batched {bt.cpu:.2f} s CPU, "
          f"per-run {pr.cpu:.2f} s")
    figure("batched eval, 1000-beacon map, 2 in view (CPU)", bt.cpu, "s", peer="per-run path",
           peer_value=pr.cpu)
    print(f"load average at end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    t0 = time.perf_counter()
    main()
    print(f"({time.perf_counter() - t0:.0f} s)")
