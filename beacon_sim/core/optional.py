"""Optional libraries: one place that imports them and one install hint per library.

beacon-sim's base install is numpy, pygame-ce and threadpoolctl; everything else is an extra
(pyproject.toml's ``[project.optional-dependencies]``). beacon-sim is not on a package index,
so a hint names the library itself (``pip install scipy``, which works beside a wheel or a
checkout alike) and the extra for a checkout (``pip install -e '.[science]'``).
"""

from __future__ import annotations

import importlib
from types import ModuleType

#: Import name -> (the package to install, the extra that holds it, what it is for).
LIBRARIES: dict[str, tuple[str, str, str]] = {
    "scipy": ("scipy", "science", "faster exact distance transforms and assignments"),
    "yaml": ("pyyaml", "maps", "map_server YAML files in any valid YAML form"),
    "rosbags": ("rosbags", "ros", "ROS 2 bags"),
    "foxglove": ("foxglove-sdk", "mcap", "Foxglove output (MCAP files, the live server)"),
    "pandas": ("pandas", "pandas", "tables as DataFrames"),
    "matplotlib": ("matplotlib", "plot", "plots"),
    "PIL": ("pillow", "gif", "GIFs and PNG maps"),
    "gymnasium": ("gymnasium", "gym", "the Gymnasium environment"),
    "dask": ("dask[distributed]", "grade", "runs on a Dask cluster"),
}

_FOUND: dict[str, ModuleType | None] = {}


def install_hint(name: str, purpose: str | None = None) -> str:
    """One line: what needs library ``name`` (an import name of :data:`LIBRARIES`) and how to
    install it, from a wheel and from a checkout."""
    package, extra, what = LIBRARIES[name.split(".")[0]]
    return (f"{purpose or what.capitalize()} needs {package}: pip install '{package}' "
            f"(in a beacon-sim checkout: pip install -e '.[{extra}]')")


def optional(module: str) -> ModuleType | None:
    """``module`` (e.g. ``"scipy.ndimage"``) imported, or None when it is not installed
    (remembered: one import attempt per process)."""
    if module not in _FOUND:
        try:
            _FOUND[module] = importlib.import_module(module)
        except ImportError:
            _FOUND[module] = None
    return _FOUND[module]


def require(module: str, purpose: str | None = None) -> ModuleType:
    """``module`` imported, or ImportError with :func:`install_hint`'s one line."""
    mod = optional(module)
    if mod is None:
        raise ImportError(install_hint(module, purpose))
    return mod
