"""A play session killed with SIGKILL leaves a recording that replays (docs/replay.md)."""

import json
import os
import signal
import subprocess
import sys
import time

import pytest

from beacon_sim.io.recording import load_recording
from beacon_sim.runs.replay import replay_recording


@pytest.mark.skipif(sys.platform == "win32", reason="SIGKILL is POSIX")
def test_killed_play_session_replays_up_to_about_the_kill(tmp_path):
    env = {**os.environ, "SDL_VIDEODRIVER": "dummy", "SDL_AUDIODRIVER": "dummy"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "beacon_sim", "play", "default", "--filter", "dead_reckoning",
         "--autopilot"], cwd=tmp_path, env=env, stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 60
        files = []
        while time.monotonic() < deadline and not files:
            files = list((tmp_path / "recordings").glob("*.jsonl"))
            time.sleep(0.05)
        assert files, "no recording appeared"
        started = time.monotonic()
        time.sleep(3.0)
        alive = proc.poll() is None
        proc.send_signal(signal.SIGKILL)
        killed_after = time.monotonic() - started
    finally:
        proc.kill()
        proc.wait(timeout=30)
    assert alive, "the window quit by itself"
    rec = load_recording(files[0])
    assert not rec.complete  # no end line: it was killed
    last = rec.ticks[-1].tick * rec.scenario.dt
    # The window runs at x1, so about `killed_after` seconds were simulated; what was
    # flushed must reach to within about a second of that (slack for a loaded machine).
    assert last >= killed_after - 2.0, (last, killed_after)
    result = replay_recording(rec)  # raises if the truth differs from what was recorded
    assert len(result.steps) == len(rec.ticks)
    assert json.loads(files[0].read_text().splitlines()[0])["format"]
