"""Where the tests find the g2o graphs (never committed: ../shared/data/graphs beside the
checkout, or the folder in BEACON_SIM_GRAPHS); a test skips with the reason when absent."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

GRAPHS_VARIABLE = "BEACON_SIM_GRAPHS"
ROOT = Path(__file__).resolve().parent.parent


def graph_file(name: str) -> Path:
    """The path of graph ``name`` (e.g. ``intel.g2o``), or skip the test saying where it was looked for."""
    where = os.environ.get(GRAPHS_VARIABLE)
    folder = Path(where) if where else ROOT.parent / "shared" / "data" / "graphs"
    path = folder / name
    if not path.is_file():
        pytest.skip(f"{name} not found in {folder} (set {GRAPHS_VARIABLE} to the folder of the g2o graphs)")
    return path
