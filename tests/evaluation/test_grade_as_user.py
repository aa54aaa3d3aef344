"""The attack corpus graded by an ordinary user (the grader started as ``nobody`` through
``setpriv`` when the tests run as root; skipped otherwise, and when no Python with numpy
is runnable by ``nobody``: the one named by the environment variable
``BEACON_SIM_USER_PYTHON``, e.g. a virtual environment made by ``/usr/bin/python3 -m venv``
with numpy, outside a private home), at every level ``grade`` offers: every honest row
is bit for bit the honest students graded alone, every cheater fails, is flagged or does
no better than an honest EKF, the grader's memory is out of reach
(``tests/attacks/grader_memory.py``), and the grader finishes."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import tempfile
import textwrap
from pathlib import Path

import pytest

from beacon_sim.hosting.containment import bwrap_problem, package_root

ATTACKS = Path(__file__).parents[1] / "attacks"
HONEST = ("honest", "honest_tuned")
HOSTILE = ("frame_walk", "gc_search", "truth_tamper", "patch_grading", "os_exit", "file_writes",
           "global_rng", "helper_last", "functions", "forge_reply", "grader_memory", "seed_recovery",
           "probe_dodger", "watched")
NOBODY = 65534

ROOT = hasattr(os, "geteuid") and os.geteuid() == 0
pytestmark = pytest.mark.skipif(not ROOT or not shutil.which("setpriv"),
                                reason="grading as an ordinary user needs root (to become one) and setpriv")

GRADE = textwrap.dedent("""
    import json, sys
    from beacon_sim.evaluation.grading import GradeConfig, grade
    cfg = GradeConfig(scenarios=("default",), seeds=(0, 1), duration=4.0, time_limit=30.0,
                      sandbox=sys.argv[2], allow_unisolated=True)
    keys = ("pos_rmse_m", "heading_rmse_rad", "anees", "anees_verdict", "rmse_over_pcrb", "failed_runs",
            "rank", "flags", "suspicious", "failures")
    out = {}
    for which in ("class", "alone"):
        board = grade(sys.argv[1] + "/" + which, cfg, jobs=2, secret=bytes(range(32)))
        out[which] = {r["student"]: {k: r.get(k) for k in keys} for r in board.rows}
    print(json.dumps(out, default=str))
""")


def _python() -> str | None:
    """An interpreter ``nobody`` can run that imports numpy and beacon_sim, or None."""
    # Only an interpreter named for it: this one may live where ``nobody`` can start it but not
    # the grader's children (a venv whose python links into root's pyenv: the child's launch
    # is refused), which would test the machine's set-up, not the grader.
    for exe in (os.environ.get("BEACON_SIM_USER_PYTHON"),):
        if not exe:
            continue
        r = subprocess.run(["setpriv", f"--reuid={NOBODY}", f"--regid={NOBODY}", "--clear-groups", exe, "-c",
                            "import numpy, beacon_sim.evaluation.grading"], capture_output=True,
                           env={"PATH": "/usr/bin:/bin", "PYTHONPATH": str(package_root())}, cwd="/",
                           timeout=120, check=False)
        if r.returncode == 0:
            return exe
    return None


def _as_nobody(tmp: Path, sandbox: str, python: str) -> dict:
    env = {"PATH": "/usr/bin:/bin", "HOME": str(tmp), "TMPDIR": str(tmp), "PYTHONPATH": str(package_root()),
           "LANG": "C.UTF-8"}
    r = subprocess.run(["setpriv", f"--reuid={NOBODY}", f"--regid={NOBODY}", "--clear-groups", python,
                        "-c", GRADE, str(tmp), sandbox], capture_output=True, text=True, env=env,
                       cwd=str(tmp), timeout=1800, check=False)
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads(r.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("sandbox", ["process", "bwrap"])
def test_the_attack_corpus_graded_by_an_ordinary_user(sandbox):
    if sandbox == "bwrap" and bwrap_problem():
        pytest.skip(f"no bubblewrap sandbox here: {bwrap_problem()}")
    python = _python()
    if python is None:
        pytest.skip("no Python with numpy that the user nobody can run (set BEACON_SIM_USER_PYTHON)")
    tmp = Path(tempfile.mkdtemp(prefix="beacon-sim-as-user-"))
    try:
        for which, stems in (("class", HONEST + HOSTILE), ("alone", HONEST)):
            (tmp / which).mkdir()
            for stem in stems:
                shutil.copyfile(ATTACKS / f"{stem}.py", tmp / which / f"{stem}.py")
        for root, dirs, files in os.walk(tmp):
            for n in [root, *(os.path.join(root, f) for f in dirs + files)]:
                os.chown(n, NOBODY, NOBODY)
        got = _as_nobody(tmp, sandbox, python)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    klass, alone = got["class"], got["alone"]
    figures = ("pos_rmse_m", "heading_rmse_rad", "anees", "anees_verdict", "rmse_over_pcrb", "failed_runs")
    for h in HONEST:
        assert {k: klass[h][k] for k in figures} == {k: alone[h][k] for k in figures}, h
        assert klass[h]["failed_runs"] == 0
    ekf = klass["honest"]["pos_rmse_m"]
    for a in HOSTILE:
        row = klass[a]
        no_better = row["pos_rmse_m"] is not None and row["pos_rmse_m"] >= ekf
        assert row["failed_runs"] or row["flags"] or row["suspicious"] or no_better, (a, row)
    spy = klass["grader_memory"]
    read = [f for f in spy["failures"] if "read the grader's memory" in str(f.get("reason"))]
    assert not read, read
