"""Scan-based MCL (filters/particle/mcl.py) measured as AMCL's users measure it.

Run:  .venv/bin/python benchmarks/bench_mcl.py [--quick] [--trials N]

- the likelihood-field update of 10,000 particles x 60 beams, as mcl scores it (AMCL's
  ``1 + sum pz^3``, float32 end points) and as Thrun's product; target <= 5 ms;
- one whole mcl update (scoring, normalising, KLD resampling) at 10,000 particles;
- a sweep of position error and CPU time per update against the particle count (250 to
  100,000; ``--quick``: 250 to 4,000), as Beluga's reports show it: the office, tracking
  from the scenario's start, fixed counts (min_particles = max_particles), the first 60 s
  (before the kidnap), 5 seeds per count; error = position RMSE over the run, CPU = the
  median process time of predict + update per scan;
- the kidnap recovery rate in the office over seeded trials (``--trials``, default 20; 5
  quick): recovered when the estimate is within 0.5 m of the truth at the end (70 s after
  the kidnap), with its 95 % Wilson interval.

Figures are medians of CPU time beside wall time (shared machines inflate the wall).
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np
from figures import figure, median_ms

from beacon_sim.core.raycast import scan
from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.core.types import Measurement
from beacon_sim.hosting.loading import build_filter


def scoring(n_rounds: int) -> None:
    sc = load_scenario("office")
    truth = np.array([7.5, 6.0, 0.3])
    rel, r = scan(sc.world.grid, truth, 181, 4.712389, 8.0)
    m = Measurement("laser", "range_finder", np.column_stack([r, rel]), np.zeros(0, dtype=int))
    rng = np.random.default_rng(1)
    cloud = truth + rng.normal(0.0, [0.5, 0.5, 0.2], (10_000, 3))
    rows = []
    for combo in ("amcl", "product"):
        f = build_filter("mcl", sc, 1, params={"beam_combination": combo, "max_particles": 10_000,
                                                "min_particles": 10_000, "laser_max_beams": 60})
        f.poses, f.n = cloud.copy(), len(cloud)
        assert len(np.flatnonzero(r[np.round(np.linspace(0, 180, 60)).astype(int)] < 8.0)) > 40
        wall, cpu = median_ms(lambda f=f: f.scan_log_likelihood(m), n_rounds)
        rows.append((f"likelihood field ({combo}), 10k particles x 60 beams", wall, cpu, "5"))
        figure(f"mcl likelihood field ({combo}), 10k particles x 60 beams", wall, "ms",
               target=5.0, cpu=cpu)
    f = build_filter("mcl", sc, 1, params={"max_particles": 10_000, "min_particles": 10_000})

    def update():
        f.poses, f.n = cloud.copy(), len(cloud)
        f.logw = np.full(f.n, -math.log(f.n))
        f.update([m])
    wall, cpu = median_ms(update, max(5, n_rounds // 2))
    rows.append(("whole mcl update (score + KLD resample), 10k particles", wall, cpu, "-"))
    figure("mcl whole update (score, normalise, KLD resample), 10k particles x 60 beams", wall, "ms",
           cpu=cpu)
    print(f"{'what':58s} {'wall ms':>8s} {'cpu ms':>8s} {'target':>7s}")
    for what, w, c, t in rows:
        print(f"{what:58s} {w:8.3f} {c:8.3f} {t:>7s}")


def track(n: int, seed: int, seconds: float) -> tuple[float, float]:
    """Position RMSE [m] and median CPU per scan update [ms] of mcl with ``n`` particles."""
    sc = load_scenario("office")
    sim = Simulation(sc, seed=seed)
    f = build_filter("mcl", sc, seed, params={"min_particles": n, "max_particles": n})
    err2, cpu = [], []
    for _ in range(round(seconds / sc.dt)):
        st = sim.step()
        t0 = time.process_time()
        f.predict(st.control, st.dt)
        f.update(st.measurements)
        if st.measurements:
            cpu.append((time.process_time() - t0) * 1e3)
        mean, _ = f.estimate()
        err2.append(float(np.sum((mean[:2] - st.true_pose[:2]) ** 2)))
    return math.sqrt(float(np.mean(err2))), statistics.median(cpu)


def sweep(counts, seeds, seconds: float) -> None:
    print(f"\n{'particles':>10s} {'pos RMSE m':>11s} {'(worst seed)':>13s} {'cpu ms/update':>14s}")
    for n in counts:
        res = [track(n, s, seconds) for s in seeds]
        rmse = statistics.median(r[0] for r in res)
        worst = max(r[0] for r in res)
        cpu = statistics.median(r[1] for r in res)
        print(f"{n:10d} {rmse:11.3f} {worst:13.3f} {cpu:14.2f}")
        figure(f"mcl office sweep: position RMSE at {n} particles (median of {len(seeds)} seeds)",
               rmse, "m")
        figure(f"mcl office sweep: CPU per update at {n} particles", cpu, "ms", cpu=cpu)


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """The 95 % Wilson score interval of a proportion k / n."""
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return centre - half, centre + half


def recovered(seed: int) -> bool:
    """One office trial: whether mcl's estimate ends within 0.5 m of the truth (70 s after
    the kidnap). scripts/make_results.py's ``office_kidnap`` figure counts these too."""
    sc = load_scenario("office")
    sim = Simulation(sc, seed=seed)
    f = build_filter("mcl", sc, seed)
    for _ in range(round(sc.duration / sc.dt)):
        st = sim.step()
        f.predict(st.control, st.dt)
        f.update(st.measurements)
    mean, _ = f.estimate()
    return bool(np.hypot(*(mean[:2] - st.true_pose[:2])) < 0.5)


def recovery(trials: int) -> None:
    ok = sum(recovered(seed) for seed in range(1, trials + 1))
    lo, hi = wilson(ok, trials)
    print(f"\nkidnap recovery in the office: {ok}/{trials} = {ok / trials:.2f} "
          f"(95 % Wilson interval {lo:.2f} .. {hi:.2f})")
    figure(f"mcl office kidnap recovery rate over {trials} seeded trials", ok / trials, "share")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer rounds, counts and trials")
    ap.add_argument("--trials", type=int, default=None, help="kidnap trials (default 20; 5 quick)")
    ap.add_argument("--no-sweep", action="store_true", help="only the timings")
    args = ap.parse_args()
    scoring(20 if args.quick else 100)
    if args.no_sweep:
        return
    counts = (250, 1000, 4000) if args.quick else (250, 1000, 4000, 16000, 100_000)
    sweep(counts, seeds=(1, 2, 3) if args.quick else (1, 2, 3, 4, 5), seconds=30.0 if args.quick else 60.0)
    recovery(args.trials or (5 if args.quick else 20))


if __name__ == "__main__":
    main()
