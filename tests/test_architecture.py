"""The layers of docs/architecture.md, as pyproject.toml's import-linter contracts: no upward
import, no circle, pygame only in app/, matplotlib only in the evaluation's plots."""

import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def lint_imports(cwd: Path) -> subprocess.CompletedProcess:
    """``lint-imports`` over the ``beacon_sim`` found first on the path from ``cwd``."""
    code = "import sys; from importlinter.cli import lint_imports_command; sys.exit(lint_imports_command())"
    return subprocess.run([sys.executable, "-c", code, "--no-cache"], cwd=cwd, capture_output=True, text=True,
                          timeout=300, env={"PYTHONPATH": str(cwd), "PATH": "/usr/bin:/bin"})


def test_the_layer_contracts_hold():
    r = lint_imports(ROOT)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-2000:]
    assert "BROKEN" not in r.stdout


def test_the_contract_check_catches_an_upward_import(tmp_path):
    """A copy of the package whose core imports the command line: the check must fail."""
    shutil.copytree(ROOT / "beacon_sim", tmp_path / "beacon_sim",
                    ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    angles = tmp_path / "beacon_sim" / "core" / "angles.py"
    angles.write_text(angles.read_text() + "\nimport beacon_sim.cli.main  # an upward import\n")
    r = lint_imports(tmp_path)
    assert r.returncode != 0
    assert "beacon_sim.core.angles -> beacon_sim.cli.main" in r.stdout
