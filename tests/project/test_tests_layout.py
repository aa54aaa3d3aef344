"""The tests mirror the package: each test module sits in the folder of the package it tests,
no test module sits at the top of ``tests/``, and no test module imports another (what two
tests share is a helper module or a conftest fixture)."""

from __future__ import annotations

import ast
from pathlib import Path

TESTS = Path(__file__).resolve().parents[1]
ROOT = TESTS.parent
#: Folders of tests/ that are not a package of beacon_sim/ (the API and the Gym env are
#: modules at the package's top; project holds checks of the repository as a whole).
EXTRA = {"api", "project"}
NOT_TESTS = {"attacks", "data", "__pycache__"}


def test_every_test_module_is_in_a_folder_named_for_a_package():
    assert not sorted(p.name for p in TESTS.glob("test_*.py")), "test modules at the top of tests/"
    packages = {p.name for p in (ROOT / "beacon_sim").iterdir() if (p / "__init__.py").is_file()}
    folders = {p.name for p in TESTS.iterdir() if p.is_dir() and p.name not in NOT_TESTS}
    assert folders <= packages | EXTRA, sorted(folders - packages - EXTRA)
    for folder in folders:
        assert any((TESTS / folder).glob("test_*.py")), f"tests/{folder}/ holds no test module"


def test_no_test_module_imports_another():
    offenders = []
    for path in TESTS.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = []
            if isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            offenders += [f"{path.relative_to(TESTS)}: {n}" for n in names
                          if n.split(".")[-1].startswith("test_") or n.startswith("tests.")]
    assert not offenders, offenders


def test_test_module_names_are_unique():
    names = [p.name for p in TESTS.rglob("test_*.py")]
    assert len(names) == len(set(names)), sorted({n for n in names if names.count(n) > 1})
