"""The layers of docs/architecture.md, as pyproject.toml's import-linter contracts: no upward
import, no circle, pygame only in app/, matplotlib only in the evaluation's plots; and one
home per idea (the angle wrap, a sensor period in ticks, the bearing model), no module
importing another's private names."""

import ast
import io
import re
import shutil
import subprocess
import sys
import tokenize
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


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


def test_the_family_contract_catches_one_family_importing_another(tmp_path):
    """A copy of the package whose grid filter imports the particle filter (or whose shared
    home imports a family): the families' contracts must fail."""
    shutil.copytree(ROOT / "beacon_sim", tmp_path / "beacon_sim",
                    ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    corridor = tmp_path / "beacon_sim" / "filters" / "grid" / "corridor.py"
    corridor.write_text(corridor.read_text() + "\nimport beacon_sim.filters.particle.pf  # another family\n")
    resampling = tmp_path / "beacon_sim" / "filters" / "resampling.py"
    resampling.write_text(resampling.read_text() + "\nimport beacon_sim.filters.slam.base  # a family\n")
    r = lint_imports(tmp_path)
    assert r.returncode != 0
    assert "Filter families are independent BROKEN" in r.stdout
    assert "beacon_sim.filters.grid.corridor -> beacon_sim.filters.particle.pf" in r.stdout
    assert "The filters' shared home imports no family BROKEN" in r.stdout


def test_the_wire_contract_catches_a_front_end_speaking_the_wire(tmp_path):
    """A copy of the package whose evaluation imports the child protocol's frames: only the
    hosting layer may (every front end goes through hosting/client.py)."""
    shutil.copytree(ROOT / "beacon_sim", tmp_path / "beacon_sim",
                    ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    summary = tmp_path / "beacon_sim" / "evaluation" / "summary.py"
    summary.write_text(summary.read_text() + "\nimport beacon_sim.hosting.wire  # the protocol\n")
    r = lint_imports(tmp_path)
    assert r.returncode != 0
    assert "Only the hosting layer speaks the wire BROKEN" in r.stdout
    assert "beacon_sim.evaluation.summary -> beacon_sim.hosting.wire" in r.stdout


def _calls_of(name: str) -> dict[str, int]:
    """Module (relative to beacon_sim/) -> how many calls ``name(...)`` or ``X.name(...)`` it holds."""
    out: dict[str, int] = {}
    for path in sorted((ROOT / "beacon_sim").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call):
                f = node.func
                called = f.id if isinstance(f, ast.Name) else f.attr if isinstance(f, ast.Attribute) else None
                if called == name:
                    rel = str(path.relative_to(ROOT / "beacon_sim"))
                    out[rel] = out.get(rel, 0) + 1
    return out


def test_a_filter_context_and_a_filter_child_are_each_built_in_one_place():
    """``FilterContext`` is assembled by ``FilterContext.of_scenario`` alone (every front end
    and the team filters call it), a filter's child process started by
    ``hosting.client.start_child`` alone (eval, check and grade go through it)."""
    assert _calls_of("FilterContext") == {}  # of_scenario builds it as ``cls(...)``
    assert set(_calls_of("of_scenario")) >= {"hosting/loading.py", "hosting/client.py", "filters/team.py"}
    assert _calls_of("FilterChild") == {"hosting/client.py": 1}
    assert set(_calls_of("start_child")) >= {"hosting/conformance.py", "hosting/client.py"}


# -- one home per idea -------------------------------------------------------------------

PACKAGE = ROOT / "beacon_sim"
#: Each idea, the pattern that writes it out, and the only modules allowed to: its home, and
#: the hot paths that keep a fused fast form held to the home by tests/project/test_single_homes.py
#: and tests/filters/test_ekf.py. Only code counts (comments and docstrings may state the formula).
HOMES = {
    "the angle wrap": (r"%\s*\(?\s*2(\.0)?\s*\*\s*(np|math)\.pi|%\s*_?TWO_PI|np\.mod\([^)]*pi",
                       {"core/angles.py"}),
    "a sensor period in ticks": (r"round\([^)]*period[^)]*/", {"core/schedule.py"}),
    "the bearing model": (r"atan2\(\s*\w+\s*,\s*\w+\s*\)\s*-\s*\w",
                          {"core/measurement_models.py", "filters/gaussian/ekf.py",
                           "filters/gaussian/ukf.py"}),
}
#: Private names imported from another module today (the owners' files; none may be added).
KNOWN_PRIVATE_IMPORTS = {("core/batch_simulation.py", "_kidnap_text")}


def _code_lines(path: Path):
    """(line number, text) of the lines of ``path`` that are code: not comments, not inside
    a docstring."""
    doc_lines: set[int] = set()
    prev = tokenize.NEWLINE
    for tok in tokenize.generate_tokens(io.StringIO(path.read_text(encoding="utf-8")).readline):
        if tok.type == tokenize.STRING and prev in (tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT,
                                                    tokenize.NL):
            doc_lines.update(range(tok.start[0], tok.end[0] + 1))
        if tok.type not in (tokenize.COMMENT, tokenize.NL):
            prev = tok.type
    for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        if n not in doc_lines and not line.lstrip().startswith("#"):
            yield n, line.split("  #")[0]


def test_each_idea_is_written_in_its_home_only():
    stray = []
    for idea, (pattern, homes) in HOMES.items():
        rx = re.compile(pattern)
        for path in sorted(PACKAGE.rglob("*.py")):
            rel = path.relative_to(PACKAGE).as_posix()
            if rel in homes:
                continue
            stray += [f"{rel}:{n}: {idea}: {line.strip()}"
                      for n, line in _code_lines(path) if rx.search(line)]
    assert not stray, "written outside its home (call core/angles, core/schedule or " \
                      "core/measurement_models):\n" + "\n".join(stray)


def test_the_home_check_catches_a_stray_wrap(tmp_path):
    f = tmp_path / "x.py"
    f.write_text('"""a docstring with (a + pi) % (2 * np.pi) - pi"""\n# a comment: % (2 * math.pi)\n'
                 "y = (a + math.pi) % (2 * math.pi) - math.pi\n", encoding="utf-8")
    hits = [n for n, line in _code_lines(f) if re.search(HOMES["the angle wrap"][0], line)]
    assert hits == [3]


def test_no_module_imports_another_modules_private_names():
    found = set()
    for path in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("beacon_sim"):
                for alias in node.names:
                    if alias.name.startswith("_") and not alias.name.startswith("__"):
                        found.add((path.relative_to(PACKAGE).as_posix(), alias.name))
    assert found <= KNOWN_PRIVATE_IMPORTS, f"private names imported: {sorted(found - KNOWN_PRIVATE_IMPORTS)}"


# -- docs/architecture.md names every module ---------------------------------------------------

def unnamed_modules(package: Path, doc: str) -> list[str]:
    """The modules of ``package`` (paths under it, ``__init__.py`` aside) that ``doc`` does not
    name as a backticked path, e.g. `` `runs/mrclam/feeding.py` ``."""
    named = set(re.findall(r"`([\w/.]+\.py)`", doc))
    modules = sorted(p.relative_to(package).as_posix() for p in package.rglob("*.py")
                     if p.name != "__init__.py" and "__pycache__" not in p.parts)
    return [m for m in modules if m not in named]


def test_architecture_md_names_every_module():
    """A newcomer finds every module in docs/architecture.md ("Every module, floor by floor").
    A module added (or moved) without its line there is listed, to be added."""
    missing = unnamed_modules(PACKAGE, (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8"))
    assert not missing, ("docs/architecture.md does not name these modules of beacon_sim/ (add a "
                         "line each to 'Every module, floor by floor'):\n"
                         + "\n".join(f"  `{m}`" for m in missing))


def test_the_module_check_lists_a_module_the_doc_omits(tmp_path):
    (tmp_path / "core").mkdir()
    for name in ("core/__init__.py", "core/angles.py", "core/new_idea.py", "top.py"):
        (tmp_path / name).write_text("", encoding="utf-8")
    doc = "| `core/angles.py` | angles |\n`top.py` and `angles.py`"
    assert unnamed_modules(tmp_path, doc) == ["core/new_idea.py"]
