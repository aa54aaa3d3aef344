"""The package stays typed: mypy (configured in pyproject.toml: the whole package, the
window's session seam in app/team.py and app/replay.py excepted) reports no error, and the
filters users write against the installed package type-check against the ``Filter``
protocol."""

import subprocess
import sys
from pathlib import Path

import pytest

from beacon_sim.filters.registry import single_records
from beacon_sim.templates import render_template

ROOT = Path(__file__).resolve().parents[2]


def _mypy(args: list[str]) -> tuple[str, int]:
    """mypy in a process of its own: in this one (``mypy.api.run``) it took a third more CPU,
    left about two million objects for the garbage collector (a full collection in a later
    test cost seconds) and left its own collector thresholds set for every later test."""
    done = subprocess.run([sys.executable, "-m", "mypy", *args], capture_output=True, text=True,
                          timeout=600)
    return done.stdout + done.stderr, done.returncode


@pytest.fixture(scope="module")
def mypy_cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One mypy cache for the module's checks (under the session's temporary folder, nothing
    written in the checkout): the second check reads the package and numpy from what the
    first wrote instead of analysing them again. mypy checks each cached module against its
    source, so a shared cache cannot hide an error."""
    return tmp_path_factory.mktemp("mypy_cache")


def test_mypy_is_clean(monkeypatch: pytest.MonkeyPatch, mypy_cache: Path) -> None:
    monkeypatch.chdir(ROOT)  # pyproject.toml's [tool.mypy] names the files, relative to here
    report, status = _mypy(["--cache-dir", str(mypy_cache)])
    assert status == 0, f"mypy found errors:\n{report}"


def test_package_is_marked_typed() -> None:
    assert (ROOT / "beacon_sim" / "py.typed").is_file()


def test_builtin_filters_and_the_template_implement_the_protocol(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, mypy_cache: Path) -> None:
    """Structural check: every built-in filter (the registry's records) and a freshly
    rendered template are a ``Filter`` for mypy (the runner only finds out at run time),
    and every batched form a record names is a ``BatchedFilter``."""
    (tmp_path / "my_filter.py").write_text(render_template("MyFilter", "my_filter.py"),
                                           encoding="utf-8")
    records = list(single_records())   # every built-in filter, from the registry
    imports = "".join(f"from {r.module} import {r.target.partition(':')[2]}\n" for r in records)
    built = ", ".join(f"{r.target.partition(':')[2]}(ctx)" for r in records)
    batched = ", ".join(f"{r.target.partition(':')[2]}(ctx).batched(2)" for r in records if r.batched)
    (tmp_path / "uses.py").write_text(
        "from beacon_sim.filters.base import BatchedFilter, Filter, FilterContext\n" + imports
        + "from my_filter import MyFilter\n\n\n"
        "def build(ctx: FilterContext) -> list[Filter]:\n"
        f"    return [{built}, MyFilter(ctx)]\n\n\n"
        "def build_batched(ctx: FilterContext) -> list[BatchedFilter]:\n"
        f"    return [{batched}]\n",
        encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    report, status = _mypy(["--config-file", str(ROOT / "pyproject.toml"),
                            "--cache-dir", str(mypy_cache),
                            "my_filter.py", "uses.py"])
    assert status == 0, f"mypy found errors:\n{report}"
