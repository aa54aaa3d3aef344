"""Packaged filters: a distribution that registers a filter in the entry-point group
``beacon_sim.filters`` is discovered by name, listed by ``beacon-sim list`` and runs."""

from __future__ import annotations

import base64
import hashlib
import json
import os
import subprocess
import sys
import textwrap
import zipfile

import pytest

from beacon_sim.cli.main import main
from beacon_sim.core.scenario import load_scenario
from beacon_sim.hosting.loading import (
    ENTRY_POINT_GROUP,
    available_filters,
    build_filter,
    load_filter_class,
)
from beacon_sim.runs.headless import run_headless

MODULE = textwrap.dedent("""
    from beacon_sim.filters.gaussian.dead_reckoning import DeadReckoning

    class PackagedFilter(DeadReckoning):
        '''Dead reckoning, shipped in a package of its own.'''
""")


def write_distribution(root, dist, module, entry_points):
    """A package ``module`` and an installed-looking ``dist-0.1.dist-info`` under ``root``."""
    pkg = root / module
    pkg.mkdir()
    (pkg / "__init__.py").write_text(MODULE)
    info = root / f"{dist}-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: 0.1\n")
    lines = "".join(f"{name} = {target}\n" for name, target in entry_points.items())
    (info / "entry_points.txt").write_text(f"[{ENTRY_POINT_GROUP}]\n{lines}")


@pytest.fixture
def installed(tmp_path, monkeypatch):
    """A distribution with one good and one broken entry point, on sys.path for this test."""
    write_distribution(tmp_path, "bsim_ep_demo", "bsim_ep_demo", {
        "packaged_dr": "bsim_ep_demo:PackagedFilter",
        "broken_ep": "bsim_ep_missing_module:Nothing",
    })
    monkeypatch.syspath_prepend(str(tmp_path))
    yield tmp_path
    sys.modules.pop("bsim_ep_demo", None)


def test_not_there_without_the_distribution():
    assert "packaged_dr" not in available_filters()


def test_entry_point_is_discovered_and_loads(installed):
    names = available_filters()
    assert "packaged_dr" in names and "broken_ep" in names
    assert names.index("dead_reckoning") < names.index("packaged_dr")   # built-ins first
    cls = load_filter_class("packaged_dr")
    assert cls.__name__ == "PackagedFilter" and cls.__module__ == "bsim_ep_demo"


def test_entry_point_filter_runs_like_a_builtin(installed):
    scenario = load_scenario("default")
    flt = build_filter("packaged_dr", scenario, 2)
    assert flt.ctx.name == "packaged_dr"
    res = run_headless(scenario, ["packaged_dr", "dead_reckoning"], seed=2, duration=3.0)
    rows = res.filter_summary()
    assert "failed" not in rows["packaged_dr"]
    # the same maths as the built-in dead reckoning, on the same steps
    assert rows["packaged_dr"]["pos_rmse_m"] == rows["dead_reckoning"]["pos_rmse_m"]


def test_list_command_shows_it(installed, capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    filters = out.split("filters:")[1].split()
    assert "packaged_dr" in filters


def test_broken_entry_point_is_a_one_line_error(installed, capsys):
    code = main(["run", "default", "--filter", "broken_ep", "--duration", "1"])
    err = capsys.readouterr().err
    assert code == 2
    assert "broken_ep" in err and "bsim_ep_missing_module" in err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1


def _wheel(tmp_path):
    """Build a real wheel by hand (a zip with a dist-info and a RECORD); no build backend needed."""
    files = {
        "bsim_wheel_demo/__init__.py": MODULE,
        "bsim_wheel_demo-0.1.dist-info/METADATA":
            "Metadata-Version: 2.1\nName: bsim-wheel-demo\nVersion: 0.1\n",
        "bsim_wheel_demo-0.1.dist-info/WHEEL":
            "Wheel-Version: 1.0\nGenerator: hand\nRoot-Is-Purelib: true\nTag: py3-none-any\n",
        "bsim_wheel_demo-0.1.dist-info/entry_points.txt":
            f"[{ENTRY_POINT_GROUP}]\nwheel_dr = bsim_wheel_demo:PackagedFilter\n",
    }
    record = []
    for name, text in files.items():
        data = text.encode()
        digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
        record.append(f"{name},sha256={digest},{len(data)}")
    record.append("bsim_wheel_demo-0.1.dist-info/RECORD,,")
    files["bsim_wheel_demo-0.1.dist-info/RECORD"] = "\n".join(record) + "\n"
    path = tmp_path / "bsim_wheel_demo-0.1-py3-none-any.whl"
    with zipfile.ZipFile(path, "w") as zf:
        for name, text in files.items():
            zf.writestr(name, text)
    return path


def test_pip_installed_distribution_is_found_by_a_fresh_process(tmp_path):
    """pip installs a wheel into a separate folder; a new ``beacon-sim`` process sees it."""
    target = tmp_path / "site"
    pip = subprocess.run(
        [sys.executable, "-m", "pip", "install", "--no-deps", "--no-index", "--quiet",
         "--disable-pip-version-check", "--target", str(target), str(_wheel(tmp_path))],
        capture_output=True, text=True, timeout=120)
    if pip.returncode != 0 and "No module named pip" in pip.stderr:
        pytest.skip("pip is not installed in this environment")
    assert pip.returncode == 0, pip.stderr
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(target), os.environ.get("PYTHONPATH", "")]))
    out = subprocess.run([sys.executable, "-m", "beacon_sim", "list"], env=env,
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert "wheel_dr" in out.stdout.split("filters:")[1].split()
    run = subprocess.run([sys.executable, "-m", "beacon_sim", "run", "default", "--filter",
                          "wheel_dr", "--duration", "1", "--json"], env=env,
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    row = json.loads(run.stdout)["filters"]["wheel_dr"]
    assert "failed" not in row and row["pos_rmse_m"] >= 0.0
