"""The core and the filters never load pygame, even at run time (docs/architecture.md)."""

import subprocess
import sys

CODE = """
import sys, pkgutil, importlib
import beacon_sim.core, beacon_sim.filters
for pkg in (beacon_sim.core, beacon_sim.filters):
    for m in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + "."):
        importlib.import_module(m.name)
import beacon_sim.runs.headless, beacon_sim.runs.replay, beacon_sim.runs.mrclam, beacon_sim.io.export
print("pygame" in sys.modules)
"""


def test_core_and_filters_do_not_import_pygame():
    r = subprocess.run([sys.executable, "-c", CODE], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "False"


def test_the_check_can_fail():
    r = subprocess.run([sys.executable, "-c", CODE.replace("print(", "import pygame; print(")],
                       capture_output=True, text=True, timeout=120)
    assert r.stdout.strip().endswith("True")
