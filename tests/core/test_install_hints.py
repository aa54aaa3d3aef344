"""Every optional library has one install hint that works from a checkout and from a wheel:
it names the library itself and the extra that holds it, and that extra exists."""

from __future__ import annotations

import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from beacon_sim.core import optional
from beacon_sim.core.optional import LIBRARIES, install_hint, require

ROOT = Path(__file__).resolve().parents[2]


def test_each_hint_names_a_real_extra_holding_the_library():
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    for name, (package, extra, _) in LIBRARIES.items():
        hint = install_hint(name)
        assert "\n" not in hint and f"pip install '{package}'" in hint and f"'.[{extra}]'" in hint
        assert any(dep.lower().startswith(package.lower()) for dep in extras[extra]), (extra, package)


def test_no_hint_points_at_a_package_index_beacon_sim_is_not_on():
    stray = [f"{p.relative_to(ROOT)}:{n}" for p in sorted((ROOT / "beacon_sim").rglob("*.py"))
             for n, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1) if "beacon-sim[" in line]
    assert not stray


def test_a_missing_library_is_one_line(monkeypatch):
    monkeypatch.setitem(optional._FOUND, "scipy.ndimage", None)
    with pytest.raises(ImportError, match=r"^Faster .* needs scipy: pip install 'scipy' \(in a beacon-sim "
                                          r"checkout: pip install -e '\.\[science\]'\)$"):
        require("scipy.ndimage")


def test_gym_without_gymnasium_says_what_to_install():
    code = ("import sys; sys.modules['gymnasium'] = None\n"
            "try:\n    import beacon_sim.gym\nexcept ImportError as e:\n    print(e)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert out.stdout.strip() == install_hint("gymnasium", "beacon_sim.gym (the Gymnasium environment)")
    assert "pip install 'gymnasium'" in out.stdout and out.stderr == ""
