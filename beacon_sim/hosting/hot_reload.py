"""Hot reload: rebuild a filter when its source file changes on disk.

The window calls :meth:`FilterFileWatcher.poll` from its loop (it only looks at the file's
modification time, at most once per ``interval`` seconds). When the file changed, the
filter is imported again and built fresh with :func:`beacon_sim.hosting.loading.build_filter`,
so it restarts from the scenario's initial belief with its own random stream from the start.
When the new version cannot be imported or built, ``poll`` returns the error and the caller
keeps running the previous version.

Works for file specs (``path/to/my_filter.py:MyFilter``) and for module specs, built-in
names and entry points whose module is a file (``pkg.mod:Class``; the module is reloaded).
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from beacon_sim.core.scenario import Scenario
from beacon_sim.filters.base import Filter, FilterError
from beacon_sim.hosting.loading import (
    BUILTIN_FILTERS,
    WINDOW_BUILD_LIMIT_S,
    build_filter,
    entry_point_filters,
    filter_display_name,
    split_label,
)
from beacon_sim.hosting.runner import FilterRunner, FilterTrack


@dataclass(frozen=True)
class ReloadResult:
    """What one poll found.

    Attributes
    ----------
    new_filter : Filter or None
        The rebuilt, reset filter when the file changed and loaded; else None.
    error : str or None
        One line to show on screen when the changed file could not be loaded (the caller
        keeps the previous version); else None.
    traceback : str
        The full traceback of that error, for the terminal ("" when there is none).
    message : str
        What to show on screen: "reloaded ..." or the error; "" when nothing changed.
    """

    new_filter: Filter | None = None
    error: str | None = None
    traceback: str = ""
    message: str = ""

    @property
    def changed(self) -> bool:
        """True when the file changed (whether or not the new version loaded)."""
        return self.new_filter is not None or self.error is not None


def source_of(spec: str) -> tuple[Path | None, str | None]:
    """The source file behind a filter spec and, for module specs, the module's name.

    ``(path, None)`` for ``file.py:Class``; ``(path, "pkg.mod")`` for module specs, built-in
    names and entry points; ``(None, None)`` when there is no file to watch.
    """
    spec = split_label(spec)[1]
    target = spec
    if spec in BUILTIN_FILTERS:
        target = BUILTIN_FILTERS[spec]
    elif ":" not in spec:
        ep = entry_point_filters().get(spec)
        if ep is None:
            return None, None
        target = ep.value
    module, _, _ = target.rpartition(":")
    if module.endswith(".py") or "/" in module or "\\" in module:
        return Path(module), None
    try:
        found = importlib.util.find_spec(module)
    except (ImportError, ValueError):
        return None, None
    if found is None or not found.origin or not Path(found.origin).is_file():
        return None, None
    return Path(found.origin), module


def _signature(path: Path) -> tuple[int, int] | None:
    """(mtime [ns], size [bytes]) of ``path``, or None when it is missing."""
    try:
        st = path.stat()
    except OSError:
        return None
    return st.st_mtime_ns, st.st_size


class FilterFileWatcher:
    """Watches one filter's source file and rebuilds the filter when it changes.

    Parameters
    ----------
    spec : str
        The filter spec as given to ``--filter`` (``./my_filter.py:MyFilter``, ``pkg.mod:Class``...).
    scenario : Scenario
        The running scenario: the new filter gets its context and initial belief.
    seed : int
        The run's seed (the new filter's random stream comes from the seed and ``name``).
    name : str, optional
        The filter's name in the run (default: as ``build_filter`` names it).
    params : dict, optional
        The ``--set`` parameters for this filter.
    interval : float
        Look at the file at most once per ``interval`` seconds of ``clock`` [s].
    clock : callable
        Time source [s]; ``time.monotonic`` by default (tests pass their own).
    """

    def __init__(self, spec: str, scenario: Scenario, seed: int, name: str | None = None,
                 params: dict[str, Any] | None = None, *, interval: float = 1.0,
                 clock: Callable[[], float] = time.monotonic):
        self.spec = spec
        self.scenario = scenario
        self.seed = seed
        self.name = name or filter_display_name(spec)
        self.params = dict(params or {})
        self.interval = float(interval)
        self.clock = clock
        self.path, self.module = source_of(spec)
        self._signature = _signature(self.path) if self.path else None
        self._last_check = clock()
        self.reloads = 0

    @property
    def watchable(self) -> bool:
        """True when there is a source file to watch."""
        return self.path is not None

    def poll(self) -> ReloadResult:
        """Check the file (at most once per ``interval``); rebuild the filter if it changed.

        Returns an empty result when nothing changed or it is too early to look again.
        """
        if self.path is None:
            return ReloadResult()
        now = self.clock()
        if now - self._last_check < self.interval:
            return ReloadResult()
        self._last_check = now
        sig = _signature(self.path)
        if sig == self._signature:
            return ReloadResult()
        self._signature = sig
        if sig is None:
            msg = f"{self.name}: {self.path} is gone; the previous version keeps running"
            return ReloadResult(error=msg, message=msg)
        return self.reload()

    def reload(self) -> ReloadResult:
        """Import the source again and build a fresh filter, whatever the file's time says."""
        try:
            if self.module is not None and self.module in sys.modules:
                importlib.reload(sys.modules[self.module])
            flt = build_filter(self.spec, self.scenario, self.seed, name=self.name,
                               params=self.params, limit_s=WINDOW_BUILD_LIMIT_S)
        except Exception as exc:  # a student's file: report it, keep the previous version
            text = str(exc) if isinstance(exc, FilterError) else f"{type(exc).__name__}: {exc}"
            first = text.splitlines()[0] if text else type(exc).__name__
            msg = f"{self.name} not reloaded: {first}; the previous version keeps running"
            return ReloadResult(error=msg, traceback=traceback.format_exc(), message=msg)
        self.reloads += 1
        where = self.path.name if self.path else self.spec
        return ReloadResult(new_filter=flt,
                            message=f"{self.name} reloaded from {where}; restarted from the "
                                    f"initial belief")


def replace_in_runner(runner: FilterRunner, name: str, new_filter: Filter) -> None:
    """Put a reloaded filter into a :class:`~beacon_sim.hosting.runner.FilterRunner` under
    ``name`` with a fresh track (no history, not failed, no slow warning)."""
    runner.tracks[name] = FilterTrack(name, new_filter)


__all__ = ["FilterFileWatcher", "ReloadResult", "replace_in_runner", "source_of"]
