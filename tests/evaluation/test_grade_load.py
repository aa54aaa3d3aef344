"""The same class gets the same verdicts on a quiet machine and on a loaded one (the machine
as it is, then with eight more busy-spinning processes: a load about ten higher): every
limit is CPU time, never wall time, so a filter near its budget, one that sleeps, the
attackers and the honest students keep their verdicts, figures and ranks. Only the cost
figures (the time per step and its "slow" flag) may differ."""

from __future__ import annotations

import contextlib
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

from beacon_sim.evaluation.grading import GradeConfig, grade

ATTACKS = Path(__file__).parents[1] / "attacks"
CORPUS = ("honest", "honest_tuned", "os_exit", "global_rng", "probe_dodger", "frame_walk", "helper_last")
SPINNERS = 8
HEAD = textwrap.dedent("""
    import time
    from beacon_sim.filters.gaussian.ekf import ExtendedKalmanFilter


    def burn(seconds):
        t0 = time.thread_time()
        while time.thread_time() - t0 < seconds:
            pass
""")
#: two_rooms at 0.1 s a tick: 4 s is 40 ticks, against 1 s of CPU per run.
EDGES = {
    "heavy": "class Heavy(ExtendedKalmanFilter):\n    def predict(self, control, dt):\n"
             "        super().predict(control, dt)\n        burn(0.06)  # 2.4 s a run: over\n",
    "light": "class Light(ExtendedKalmanFilter):\n    def predict(self, control, dt):\n"
             "        super().predict(control, dt)\n        burn(0.01)  # 0.4 s a run: within\n",
    "sleepy": "class Sleepy(ExtendedKalmanFilter):\n    def predict(self, control, dt):\n"
              "        super().predict(control, dt)\n        time.sleep(0.05)  # a wait: no CPU\n",
}
CONFIG = GradeConfig(scenarios=("two_rooms",), seeds=(0, 1), duration=4.0, time_limit=1.0, sandbox="auto",
                     allow_unisolated=True)
VERDICT = ("failed_runs", "pos_rmse_m", "heading_rmse_rad", "anees", "anees_verdict", "rmse_over_pcrb",
           "deterministic", "readings_used", "suspicious", "rank")


@contextlib.contextmanager
def spinning(n: int):
    procs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]
    try:
        yield procs
    finally:
        for p in procs:
            p.kill()
        for p in procs:
            p.wait(timeout=30)


def _verdicts(folder: Path) -> dict:
    rows = grade(folder, CONFIG, jobs=2, secret=bytes(range(32))).rows
    return {r["student"]: ({k: r.get(k) for k in VERDICT}, sorted(f["reason"] for f in r["failures"]),
                           [f for f in r["flags"] if not f.startswith("slow")]) for r in rows}


def test_a_class_gets_the_same_verdicts_on_a_quiet_and_a_loaded_machine(tmp_path):
    folder = tmp_path / "class"
    folder.mkdir()
    for stem in CORPUS:
        shutil.copyfile(ATTACKS / f"{stem}.py", folder / f"{stem}.py")
    for name, body in EDGES.items():
        (folder / f"{name}.py").write_text(HEAD + "\n\n" + body)
    quiet = _verdicts(folder)
    with spinning(SPINNERS):
        loaded = _verdicts(folder)
    assert loaded == quiet
    assert quiet["heavy"][0]["failed_runs"] == 2 and quiet["light"][0]["failed_runs"] == 0
    assert quiet["sleepy"][0]["failed_runs"] == 0 and quiet["os_exit"][0]["failed_runs"] == 2
