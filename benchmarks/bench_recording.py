"""What a version 3 recording costs: a live session of the default scenario on
autopilot with the EKF and dead reckoning, recorded (filter settings, estimate digests every
checkpoint), then loaded and replayed with every check; the peer is the same session without
a recorder.

    python benchmarks/bench_recording.py [--ticks 20000]

Prints the file's size per tick and the CPU times of recording, loading and replaying.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from figures import figure  # (benchmarks/ is on sys.path: the script's own folder)

from beacon_sim.core.scenario import load_scenario
from beacon_sim.io.recording import load_recording
from beacon_sim.runs.live import Session
from beacon_sim.runs.recorder import Recorder
from beacon_sim.runs.replay import replay_recording

FILTERS = ["ekf", "dead_reckoning"]


def session_cpu(ticks: int, path: Path | None) -> float:
    """CPU seconds of ``ticks`` autopilot ticks (recorded to ``path`` unless None)."""
    sc = load_scenario("default")
    rec = Recorder(path, sc, 1, FILTERS) if path is not None else None
    s = Session(sc, FILTERS, 1, {}, rec)
    s.toggle_autopilot()
    t0 = time.process_time()
    for _ in range(ticks):
        s.tick()
    s.close()
    return time.process_time() - t0


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--ticks", type=int, default=20000)
    n = ap.parse_args().ticks
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "run.jsonl"
        bare = session_cpu(n, None)
        recorded = session_cpu(n, path)
        size = path.stat().st_size
        t0 = time.process_time()
        rec = load_recording(path)
        t1 = time.process_time()
        res = replay_recording(rec)
        t2 = time.process_time()
    status = res.extra["replay"]["checksum_status"]
    print(f"{n} ticks: {size / n:.0f} bytes a tick; session {bare:.2f} s CPU, recorded "
          f"{recorded:.2f} s ({recorded / bare:.2f}x); load {t1 - t0:.2f} s, replay "
          f"{t2 - t1:.2f} s ({status})")
    figure("recorded session (ekf + dead reckoning)", recorded / n * 1e6, "us", peer="unrecorded",
           peer_value=bare / n * 1e6, cpu=recorded / n * 1e6)
    figure("recording load, per tick", (t1 - t0) / n * 1e6, "us", cpu=(t1 - t0) / n * 1e6)
    figure("replay with every check, per tick", (t2 - t1) / n * 1e6, "us", cpu=(t2 - t1) / n * 1e6)
    figure("recording size, per tick", size / n, "bytes")
    return 0 if status == "verified" else 1


if __name__ == "__main__":
    sys.exit(main())
