"""The key tables in README.md and docs/window.md are the window's own (controls.py's
binding tables, which also drive the key handler and the help overlay). After changing a
binding, regenerate them with::

    python -c "from beacon_sim.app.controls import markdown_table; print(markdown_table('play'))"
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from beacon_sim.app import controls

ROOT = Path(__file__).resolve().parents[2]


def tables(path: Path) -> list[str]:
    """Every Markdown table in the file that starts with a ``| keys | action |`` header."""
    text = path.read_text(encoding="utf-8")
    return [m.group(0) for m in re.finditer(r"^\| keys \| action \|\n(?:\|.*\|\n)+", text, re.M)]


@pytest.mark.parametrize("doc, modes", [("README.md", ["play"]),
                                        ("docs/window.md", ["play", "replay"])])
def test_key_tables_match_the_bindings(doc, modes):
    found = tables(ROOT / doc)
    assert found == [controls.markdown_table(m) for m in modes], (
        f"{doc}: the key table differs from beacon_sim/app/controls.py; regenerate it "
        "(see this test's docstring)")


def test_every_binding_is_in_the_readme_once():
    readme = tables(ROOT / "README.md")[0]
    for b in controls.BINDINGS:
        assert readme.count(f"| `{b.keys}` |") == 1, b.keys
