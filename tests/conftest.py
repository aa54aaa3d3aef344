"""Test-wide settings: pygame renders off-screen and makes no sound; the MRCLAM data set;
the ``slow`` tier (the real MRCLAM data set's whole runs, the largest Monte Carlo sets) runs
only when asked for."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from beacon_sim.io.mrclam import MRCLAM_DOC, MRCLAM_VARIABLE, MrclamError, find_dataset

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")


def pytest_addoption(parser):
    parser.addoption("--run-slow", action="store_true", default=False,
                     help="also run the tests marked slow (CI does; README.md, 'Set up')")


def pytest_collection_modifyitems(config, items):
    """Without ``--run-slow`` (and without a ``-m`` of one's own) the tests marked ``slow``
    are deselected, so README's test command stays within minutes; ``-m slow`` runs that
    tier alone, ``--run-slow`` everything."""
    if config.getoption("--run-slow") or config.getoption("markexpr"):
        return
    slow = [item for item in items if item.get_closest_marker("slow")]
    if slow:
        config.hook.pytest_deselected(items=slow)
        items[:] = [item for item in items if not item.get_closest_marker("slow")]


#: Where ``play`` records when run from the checkout: tests write only under tmp_path.
_CHECKOUT_RECORDINGS = Path(__file__).resolve().parents[1] / "recordings"


def _recordings_in_the_checkout() -> set[Path]:
    return set(_CHECKOUT_RECORDINGS.glob("*")) if _CHECKOUT_RECORDINGS.is_dir() else set()


@pytest.fixture(autouse=True)
def _no_recordings_in_the_checkout():
    """Fail the test that leaves a new file in the checkout's recordings/ (a test
    that plays must pass --no-record or chdir to its tmp_path)."""
    before = _recordings_in_the_checkout()
    yield
    new = sorted(p.name for p in _recordings_in_the_checkout() - before)
    assert not new, f"the test wrote into the checkout's recordings/: {new[:3]}"


def _find_dataset6() -> tuple[Path | None, str]:
    """MRCLAM Dataset 6 for the tests, and why not when absent: where ``$BEACON_SIM_MRCLAM``
    says (a data set's folder or the folder holding Dataset6), else ``shared/data/mrclam``
    beside the checkout (or beside the folder of worktrees that holds it). Never committed."""
    where = None  # find_dataset reads the variable
    if not os.environ.get(MRCLAM_VARIABLE):
        checkout = Path(__file__).resolve().parents[1]
        beside = [up / "shared" / "data" / "mrclam" for up in (checkout.parent, checkout.parent.parent)]
        where = next((p for p in beside if p.is_dir()), None)
        if where is None:
            return None, (f"MRCLAM Dataset 6 not found: set {MRCLAM_VARIABLE} to its folder or to "
                          f"the folder holding it ({MRCLAM_DOC})")
    try:
        return find_dataset(where, 6), ""
    except MrclamError as exc:
        return None, f"MRCLAM Dataset 6 not found: {exc}"


DATASET6, _NO_DATASET6 = _find_dataset6()


@pytest.fixture(scope="session")
def mrclam_dataset6() -> Path:
    """The folder of MRCLAM Dataset 6 (the one home of the tests that need the real data);
    the test is skipped, with the reason, when it is absent."""
    if DATASET6 is None:
        pytest.skip(_NO_DATASET6)
    return DATASET6


@pytest.fixture(scope="session")
def mrclam_calibration():
    """``leave_one_robot_out(data)`` (what ``run_mrclam``'s default ``calibration="others"``
    computes: the other robots' noise, inflated by EKF runs over each of them, about 7 s of CPU
    on Dataset 6), once per folder and robot in a session. The tests that score one robot's
    run on Dataset 6 pass it as ``calibration=``, which gives the default's run bit for bit."""
    from beacon_sim.runs.mrclam import leave_one_robot_out

    cache = {}

    def calibration(data):
        key = (Path(data.folder).resolve(), data.robot)
        if key not in cache:
            cache[key] = leave_one_robot_out(data)
        return cache[key]

    return calibration


@pytest.fixture()
def busy_machine():
    """Two busy-spinning processes beside the test (an artificial load), for the tests that
    show a verdict does not depend on the machine's load."""
    procs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(2)]
    try:
        yield procs
    finally:
        for p in procs:
            p.kill()
        for p in procs:
            p.wait(timeout=30)
