"""The window's frame time in the heaviest classroom view and the default view, against an
older commit in the same run.

Views (SDL dummy driver, scripted frames of 1/60 s, autopilot, x1):

- ``heavy``: ekf + ukf + pf (10,000 particles) + histogram on ``default`` (dt = 0.05 s: one
  frame in three carries a tick), the teacher's global-localization view;
- ``heavy_kidnap``: the same filters on ``global_kidnap`` (a spread belief: big ellipses,
  particles over the whole room);
- ``light``: ekf + dead_reckoning on ``default`` (the default view).

Each (code, view, size) runs in its own process, kept alive: the script asks each in turn
for a round of 240 frames, the code under test and the base commit alternating, so both meet
the same load. A frame's cost is the whole process's CPU time (``time.process_time``: every
thread) and its interval (``time.perf_counter``: scripted frames do not wait, so this is
the wall time the frame took). Printed: median and 99th percentile per round, the medians of
the rounds, and FIGURE lines for the heavy view's p99 (targets 8 ms at 1280x800, 10 ms at
1920x1080, at load < 2) and for the light view against the base commit (no slower: <= 1.1x).
The processes switch on what ``App.run`` does (the heap settling of ``app/heap.py``, the
smooth drawing of ``App.draw``).

    python benchmarks/bench_frames.py [--rounds 5] [--frames 240] [--base 62f69b5]
        [--views heavy light] [--sizes 1280x800 1920x1080]

``--base REV`` extracts that commit (``git archive``) to a temporary folder and imports it
from there; ``--base none`` measures only the working tree.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tarfile
import tempfile
import time
from io import BytesIO
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

VIEWS = {
    "heavy": ("default", ["ekf", "ukf", "pf", "histogram"]),
    "heavy_kidnap": ("global_kidnap", ["ekf", "ukf", "pf", "histogram"]),
    "light": ("default", ["ekf", "dead_reckoning"]),
}
#: p99 targets of the heavy views [ms] by window size (at load < 2).
TARGETS = {"1280x800": 8.0, "1920x1080": 10.0}
#: The light view may be at most this much slower than the base commit (p99 ratio).
LIGHT_RATIO = 1.1
WARMUP = 30


def worker(view: str, size: str) -> None:
    """Build the view, then run a round of frames per line read from stdin; print JSON."""
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
    from beacon_sim.core.threads import limit_blas_threads

    limit_blas_threads()
    import beacon_sim
    from beacon_sim.app.main import SCRIPTED_FRAME_S, App
    from beacon_sim.core.scenario import load_scenario
    from beacon_sim.runs.live import Session

    scenario, specs = VIEWS[view]
    w, h = (int(v) for v in size.split("x"))
    session = Session(load_scenario(scenario), specs, None, {"pf": {"n_particles": 10_000}})
    session.toggle_autopilot()
    app = App(session, (w, h), scripted=True)
    # What App.run switches on (an older commit has no such switches: no effect there).
    app.settle_heap = True
    app.smooth = True
    for _ in range(WARMUP):
        app.frame(SCRIPTED_FRAME_S)
    print(json.dumps({"ready": str(Path(beacon_sim.__file__).parent)}), flush=True)
    for line in sys.stdin:
        frames = int(line)
        cpu, wall, ticks = [], [], []
        for _ in range(frames):
            c0, t0 = time.process_time(), time.perf_counter()
            app.frame(SCRIPTED_FRAME_S)
            wall.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
            ticks.append(app.ticks_this_frame)
        # A filter switched off (the window's time limit on a step, under load) lightens the
        # view: reported beside the round.
        failed = [n for n, t in session.runner.tracks.items() if t.failed]
        print(json.dumps({"cpu": cpu, "wall": wall, "ticks": ticks, "failed": failed,
                          "load": os.getloadavg()[0]}), flush=True)
    app.close()


def extract(rev: str) -> Path:
    """A checkout of commit ``rev`` (no .git) in a temporary folder (``git archive``)."""
    out = Path(tempfile.mkdtemp(prefix=f"beacon-sim-{rev}-"))
    data = subprocess.run(["git", "-C", str(ROOT), "archive", rev],
                          check=True, capture_output=True).stdout
    with tarfile.open(fileobj=BytesIO(data)) as tar:
        tar.extractall(out, filter="data")
    return out


def start(view: str, size: str, path: Path) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(path)}
    p = subprocess.Popen([sys.executable, __file__, "--worker", view, size], cwd=path, env=env,
                         stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    return p


def ask(p: subprocess.Popen, frames: int) -> dict:
    assert p.stdin is not None and p.stdout is not None
    p.stdin.write(f"{frames}\n")
    p.stdin.flush()
    return json.loads(p.stdout.readline())


def pct(xs: list[float], q: float) -> float:
    s = sorted(xs)
    k = (len(s) - 1) * q / 100.0
    i = int(k)
    return s[i] if i + 1 >= len(s) else s[i] + (s[i + 1] - s[i]) * (k - i)


def median(xs: list[float]) -> float:
    return pct(xs, 50.0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worker", nargs=2, metavar=("VIEW", "SIZE"), help=argparse.SUPPRESS)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--frames", type=int, default=240)
    ap.add_argument("--base", default="62f69b5", help="commit to compare with, or 'none'")
    ap.add_argument("--views", nargs="+", default=["heavy", "heavy_kidnap", "light"],
                    choices=sorted(VIEWS))
    ap.add_argument("--sizes", nargs="+", default=list(TARGETS))
    args = ap.parse_args()
    if args.worker:
        worker(*args.worker)
        return
    codes = {"new": ROOT}
    if args.base.lower() != "none":
        codes["base"] = extract(args.base)
    try:
        measure(args, codes)
    finally:
        if "base" in codes:
            shutil.rmtree(codes["base"], ignore_errors=True)


def measure(args: argparse.Namespace, codes: dict[str, Path]) -> None:
    """Start the worker processes, ask them for the rounds in turn, print the figures."""
    from figures import figure

    procs = {}
    for view in args.views:
        for size in args.sizes:
            for code, path in codes.items():
                procs[code, view, size] = start(view, size, path)
    for key, p in procs.items():
        assert p.stdout is not None
        ready = json.loads(p.stdout.readline())
        if key[1] == args.views[0] and key[2] == args.sizes[0]:
            print(f"{key[0]}: {ready['ready']}")
    load0 = os.getloadavg()[0]
    rounds: dict[tuple, list[dict]] = {k: [] for k in procs}
    for r in range(args.rounds):
        for view in args.views:
            for size in args.sizes:
                order = list(codes) if r % 2 == 0 else list(codes)[::-1]
                for code in order:
                    res = ask(procs[code, view, size], args.frames)
                    ms = [1e3 * c for c in res["cpu"]]
                    wall = [1e3 * c for c in res["wall"]]
                    tick = [m for m, t in zip(ms, res["ticks"], strict=True) if t]
                    rest = [m for m, t in zip(ms, res["ticks"], strict=True) if not t]
                    row = {"p50": median(ms), "p99": pct(ms, 99), "wall_p50": median(wall),
                           "wall_p99": pct(wall, 99), "tick_p50": median(tick) if tick else 0.0,
                           "rest_p50": median(rest) if rest else 0.0, "load": res["load"]}
                    rounds[code, view, size].append(row)
                    print(f"round {r + 1} {code:4} {view:12} {size:9}: CPU p50 {row['p50']:5.2f} "
                          f"p99 {row['p99']:5.2f} ms (tick frames p50 {row['tick_p50']:5.2f}, "
                          f"others {row['rest_p50']:5.2f}); interval p50 {row['wall_p50']:5.2f} "
                          f"p99 {row['wall_p99']:5.2f} ms; load {row['load']:.1f}"
                          + (f"; SWITCHED OFF: {', '.join(res['failed'])}" if res.get("failed")
                             else ""), flush=True)
    for p in procs.values():
        assert p.stdin is not None
        p.stdin.close()
        p.wait(timeout=60)
    print(f"load average {load0:.1f} at start, {os.getloadavg()[0]:.1f} at end; medians of "
          f"{args.rounds} rounds of {args.frames} frames:")
    for view in args.views:
        for size in args.sizes:
            m = {code: {k: median([row[k] for row in rounds[code, view, size]])
                        for k in ("p50", "p99", "wall_p50", "wall_p99")} for code in codes}
            new = m["new"]
            base = m.get("base")
            vs = f" (base {base['p50']:.2f} / {base['p99']:.2f} ms, p99 {new['p99'] / base['p99']:.2f}x)" \
                if base else ""
            print(f"  {view:12} {size:9}: CPU p50 {new['p50']:.2f} p99 {new['p99']:.2f} ms, interval "
                  f"p50 {new['wall_p50']:.2f} p99 {new['wall_p99']:.2f} ms{vs}")
            what = f"frame {view} ({' + '.join(VIEWS[view][1])} on {VIEWS[view][0]}) {size}"
            if view.startswith("heavy"):
                figure(what + ", p99 CPU", new["p99"], "ms", target=TARGETS.get(size),
                       peer=f"{args.base} p99" if base else None,
                       peer_value=base["p99"] if base else None, cpu=new["p99"])
                figure(what + ", p99 interval", new["wall_p99"], "ms", target=TARGETS.get(size),
                       cpu=new["p99"])
            elif base:
                figure(what + ", p99 CPU vs base", new["p99"], "ms", peer=f"{args.base} p99",
                       peer_value=base["p99"], target=LIGHT_RATIO, target_of="ratio",
                       cpu=new["p99"])
            figure(what + ", median CPU", new["p50"], "ms",
                   peer=f"{args.base} median" if base else None,
                   peer_value=base["p50"] if base else None, cpu=new["p50"])


if __name__ == "__main__":
    main()
