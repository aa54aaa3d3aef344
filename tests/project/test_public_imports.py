"""The examples, the notebook and the ``new-filter`` templates program against the public API
only (CONTRIBUTING.md, "What is public"): every ``beacon_sim`` import they make names
``beacon_sim``, ``beacon_sim.api`` or ``beacon_sim.gym``, and every name they take from the
first two is in ``beacon_sim.__all__``."""

from __future__ import annotations

import ast
import json
from pathlib import Path

import pytest

import beacon_sim

ROOT = Path(__file__).resolve().parents[2]
#: The public modules a user's code may import from.
PUBLIC_MODULES = {"beacon_sim", "beacon_sim.api", "beacon_sim.gym"}
SOURCES = sorted([*ROOT.glob("examples/*.py"), *ROOT.glob("beacon_sim/templates/my_*.py")])
NOTEBOOKS = sorted(ROOT.glob("examples/*.ipynb"))


def private_imports(source: str) -> list[str]:
    """Every ``beacon_sim`` import of ``source`` (Python) that is not public, one line each."""
    bad = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            bad += [f"import {a.name}" for a in node.names
                    if a.name.split(".")[0] == "beacon_sim" and a.name not in PUBLIC_MODULES]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module \
                and node.module.split(".")[0] == "beacon_sim":
            if node.module not in PUBLIC_MODULES:
                bad.append(f"from {node.module} import ...")
            elif node.module in ("beacon_sim", "beacon_sim.api"):
                bad += [f"from {node.module} import {a.name}" for a in node.names
                        if a.name not in beacon_sim.__all__]
    return bad


def notebook_code(path: Path) -> str:
    cells = json.loads(path.read_text(encoding="utf-8"))["cells"]
    code = ("".join(c["source"]) if isinstance(c["source"], list) else c["source"]
            for c in cells if c["cell_type"] == "code")
    # IPython's magics and shell lines are not Python
    return "\n".join(ln for block in code for ln in block.splitlines()
                     if not ln.lstrip().startswith(("%", "!")))


def test_the_check_finds_a_private_import():
    assert private_imports("from beacon_sim.core.angles import wrap\nimport beacon_sim.core.motion\n"
                           "from beacon_sim.api import wrap, _CLASS_MODULE\nimport numpy\n") == [
        "from beacon_sim.core.angles import ...", "import beacon_sim.core.motion",
        "from beacon_sim.api import _CLASS_MODULE"]
    assert private_imports("import beacon_sim as bs\nfrom beacon_sim.gym import BeaconEnv\n") == []


def test_there_is_something_to_check():
    assert len(SOURCES) >= 6 and NOTEBOOKS


@pytest.mark.parametrize("path", SOURCES + NOTEBOOKS, ids=lambda p: str(p.relative_to(ROOT)))
def test_examples_and_templates_import_only_the_public_api(path):
    source = notebook_code(path) if path.suffix == ".ipynb" else path.read_text(encoding="utf-8")
    assert private_imports(source) == [], f"{path.relative_to(ROOT)} imports private names"


def test_every_public_name_is_there():
    for name in beacon_sim.__all__:
        assert getattr(beacon_sim, name) is not None
