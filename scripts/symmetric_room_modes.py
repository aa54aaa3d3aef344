"""How often the symmetric room's two clouds both live until the symmetry breaks.

    python scripts/symmetric_room_modes.py [--seeds 100-119] [--set mcl.KEY=VALUE ...] [--jobs 2]

Each seed runs the shipped ``symmetric_room`` scenario (started lost, mcl with the
scenario's parameters and any ``--set``) and checks, every 0.5 s, the share of mcl's weight
within ``RADIUS`` of the true position and within ``RADIUS`` of its mirror image (the pose
turned half a turn about the room's centre (4, 2)), which the room cannot tell apart until
the laser sees the partition in the south-east corner. The *breaking observation* is the
first scan of the true robot with a beam ending on the partition.

- **both live**: from ``FORMED`` s (the clouds have formed) until the breaking observation,
  both shares stay at least ``ALIVE`` at every check (checks while the truth is within
  0.35 m of the centre, where the two are the same place, are skipped);
- **right one**: at the end of the run the share near the truth is at least ``RIGHT``.

Prints one line per seed and FIGURE lines with the fractions and their 95 % Wilson intervals.
"""

from __future__ import annotations

import argparse
import math
import multiprocessing
import sys

import numpy as np

from beacon_sim.core.scenario import load_scenario
from beacon_sim.core.simulation import Simulation
from beacon_sim.hosting.loading import build_filter

RADIUS = 0.5      # [m] a mode's neighbourhood ...
HEADING = 0.5     # [rad] ... and its headings
ALIVE = 0.02      # the least share of the weight a living mode holds
FORMED = 7.5      # [s] the clouds have formed by then
RIGHT = 0.9       # share near the truth at the end for "ended at the right one"
CENTRE = np.array([4.0, 2.0])
PARTITION = (7.0, 0.0, 7.125, 1.5)  # the one thing without a twin [m]


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """The Wilson score interval of k successes in n trials."""
    if n == 0:
        return (0.0, 1.0)
    p = k / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return (max(0.0, c - h), min(1.0, c + h))


def sees_partition(pose: np.ndarray, z: np.ndarray, max_range: float) -> bool:
    """Whether a scan (rows [range, bearing]) has a beam ending on the partition (within
    5 cm of its outline)."""
    hit = z[:, 0] < max_range
    ang = pose[2] + z[hit, 1]
    ex = pose[0] + z[hit, 0] * np.cos(ang)
    ey = pose[1] + z[hit, 0] * np.sin(ang)
    x0, y0, x1, y1 = PARTITION
    on = (ex > x0 - 0.05) & (ex < x1 + 0.05) & (ey > y0 - 0.05) & (ey < y1 + 0.05)
    return bool(on.any())


def share_near(f, pose: np.ndarray) -> float:
    """The share of mcl's weight within RADIUS [m] and HEADING [rad] of ``pose``."""
    w = f.weights()
    near = np.hypot(*(f.poses[:, :2] - pose[:2]).T) < RADIUS
    near &= np.cos(f.poses[:, 2] - pose[2]) > math.cos(HEADING)
    return float(w[near].sum())


def mirror(pose: np.ndarray) -> np.ndarray:
    """The pose turned half a turn about the room's centre: it sees the same scan."""
    return np.array([2 * CENTRE[0] - pose[0], 2 * CENTRE[1] - pose[1], pose[2] + math.pi])


def one_run(args: tuple[int, dict], until_break: bool = False) -> dict:
    """One seed's run: when the symmetry broke [s] (None: never), whether both modes lived
    until then, the least shares each had, the share near the truth at the end (the end of
    the run, or with ``until_break`` the breaking observation) and whether that is RIGHT."""
    seed, params = args
    sc = load_scenario("symmetric_room")
    sim = Simulation(sc, seed=seed)
    f = build_filter("mcl", sc, seed, params=params or None)
    max_range = sc.sensors[0].max_range
    broke = None
    both = True
    lowest = (1.0, 1.0)
    stride = round(0.5 / sc.dt)
    for k in range(1, round(sc.duration / sc.dt) + 1):
        st = sim.step()
        f.predict(st.control, st.dt)
        f.update(st.measurements)
        if broke is None:
            for m in st.measurements:
                if m.kind == "range_finder" and sees_partition(st.true_pose, m.z, max_range):
                    broke = st.time
            if broke is not None and until_break:
                break
        if broke is None and k % stride == 0 and st.time >= FORMED:
            truth = np.asarray(st.true_pose, dtype=float)
            if True:
                pair = (share_near(f, truth), share_near(f, mirror(truth)))
                lowest = (min(lowest[0], pair[0]), min(lowest[1], pair[1]))
                both &= min(pair) >= ALIVE
    final = share_near(f, np.asarray(st.true_pose, dtype=float))
    return {"seed": seed, "broke": broke, "both": both and broke is not None, "lowest": lowest,
            "final": final, "right": final >= RIGHT,
            "final_mirror": share_near(f, mirror(np.asarray(st.true_pose, dtype=float)))}


def parse_value(text: str):
    """A --set value: true/false, an integer, a number, else the text."""
    if text in ("true", "false"):
        return text == "true"
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def seeds_of(text: str) -> list[int]:
    out: list[int] = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out.extend(range(int(a), int(b or a) + 1))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="100-119")
    ap.add_argument("--set", action="append", default=[], metavar="mcl.KEY=VALUE")
    ap.add_argument("--jobs", type=int, default=1)
    args = ap.parse_args(argv)
    params: dict = {}
    for item in args.set:
        key, _, value = item.partition("=")
        params[key.removeprefix("mcl.")] = parse_value(value)
    seeds = seeds_of(args.seeds)
    jobs = [(s, params) for s in seeds]
    if args.jobs > 1:
        with multiprocessing.Pool(args.jobs) as pool:
            results = pool.map(one_run, jobs)
    else:
        results = [one_run(j) for j in jobs]
    for r in results:
        broke = "never" if r["broke"] is None else f"at {r['broke']:.1f} s"
        print(f"seed {r['seed']}: symmetry broken {broke}, both modes lived: {r['both']} "
              f"(least shares {r['lowest'][0]:.3f} truth, {r['lowest'][1]:.3f} mirror), "
              f"share near the truth at the end {r['final']:.3f}", flush=True)
    n = len(results)
    for key, what in (("both", "both modes live until the breaking observation"),
                      ("right", "ends on the right one")):
        k = sum(r[key] for r in results)
        lo, hi = wilson(k, n)
        print(f"FIGURE symmetric_room {what}: {k}/{n} = {k / n:.2f} (95% Wilson {lo:.2f}-{hi:.2f}); "
              f"seeds {args.seeds}{' ' + ' '.join(args.set) if args.set else ''}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
