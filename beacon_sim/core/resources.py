"""Where the shipped scenarios and assets live, installed or in a checkout.

A wheel carries them as ``beacon_sim/_data/{scenarios,assets}`` (see pyproject.toml);
a source checkout (or an editable install) has them at the top level.
"""

from __future__ import annotations

from pathlib import Path

_PACKAGE = Path(__file__).resolve().parents[1]  # beacon_sim/


def data_dir(name: str) -> Path:
    """The folder of shipped ``scenarios`` or ``assets``."""
    installed = _PACKAGE / "_data" / name
    if installed.is_dir():
        return installed
    return _PACKAGE.parent / name


def scenario_dir() -> Path:
    return data_dir("scenarios")


def asset_path(name: str) -> Path:
    return data_dir("assets") / name


def shipped_scenarios() -> list[str]:
    """Names of the shipped scenarios (file stems), sorted."""
    return sorted(p.stem for p in scenario_dir().glob("*.toml"))
